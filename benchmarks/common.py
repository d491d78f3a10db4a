"""Shared pieces of the benchmarks: where results go and what machine measured them.

Where a benchmark writes (:func:`resolve_output`): each module declares in ``CONFIGURATIONS`` the configurations
whose results are kept in ``benchmarks/results/`` (a name, and the command-line arguments that give it; its default
configuration under the module's own name) and in ``FILES`` the files it writes for one name. A run of a declared
configuration writes ``benchmarks/results/<its name>.*``; any other configuration writes to ``--out FOLDER`` or, by
default, to ``runs/benchmarks/<a name derived from the options that differ>/`` in the working folder. A run never
writes over the results of another configuration: each JSON result records its configuration, and a folder whose
files record another one (or none) is refused before anything runs.
"""

from __future__ import annotations

import argparse
import fnmatch
import hashlib
import json
import os
import platform
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco

from envs.common.host import numerics
from envs.common.io import json_default, parent_problem, write_json, write_text

RESULTS = Path(__file__).resolve().parent / "results"
RUNS = Path("runs") / "benchmarks"  # relative to the working folder: a configuration kept nowhere else
STANDARD_FILES = ("{name}.json", "{name}.md")
OUTPUT_OPTIONS = frozenset({"out", "name"})


def robot_task_ids() -> list[str]:
    """The registered ids of the robots' own tasks (walking, turning, rough ground), sorted; the soccer academy's
    ids step a shared scene with a field and a ball, which ``benchmarks.soccer_speed`` measures."""
    import gymnasium as gym

    import envs  # noqa: F401 (registers the ids)

    ids = (k for k in gym.registry if k.startswith("skitter/"))
    return sorted(k for k in ids if not str(gym.spec(k).entry_point).startswith("envs.soccer."))


def machine() -> dict[str, Any]:
    """The machine and the versions of the numerical packages a result depends on (a contact-rough fit can take
    another path on another numpy or scipy)."""
    from importlib.metadata import PackageNotFoundError, version

    versions = {}
    for package in ("numpy", "scipy", "cma", "gymnasium"):
        try:
            versions[package] = version(package)
        except PackageNotFoundError:
            versions[package] = None
    return {
        "cpu_count": os.cpu_count(),
        "processor": platform.processor() or platform.machine(),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        **versions,
        **numerics(),  # the CPU and numpy's code paths: the last bits of a result can differ between them
        "commit": _commit(),
    }


def _commit() -> str | None:
    """The repository's commit (with ``+dirty`` for uncommitted changes), if this is a git checkout."""
    import subprocess

    root = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True,
                              check=True, timeout=10).stdout.strip()  # fmt: skip
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, check=True, timeout=10).stdout.strip()  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "")


@dataclass(frozen=True)
class Output:
    """Where one run writes: ``folder/<name>.*``, and the configuration its JSON records."""

    folder: Path
    name: str
    configuration: dict[str, Any]
    kept: bool = False  # in benchmarks/results/: a configuration the module declares

    def path(self, suffix: str) -> Path:
        """``folder/<name><suffix>``, e.g. ``path(".png")``."""
        return self.folder / f"{self.name}{suffix}"

    def file(self, filename: str) -> Path:
        """Another file the benchmark writes beside its results (one of its ``FILES``)."""
        return self.folder / filename

    def save(self, result: Mapping[str, Any], markdown: str, echo: bool = True) -> None:
        """Write ``<name>.json`` (with the configuration and the machine) and ``<name>.md`` atomically and (``echo``)
        print the markdown."""
        self.folder.mkdir(parents=True, exist_ok=True)
        write_json(self.path(".json"), {**result, "configuration": self.configuration, "machine": machine()})
        write_text(self.path(".md"), markdown)
        if echo:
            print(markdown)


def add_output_options(parser: argparse.ArgumentParser) -> None:
    """``--out`` and ``--name``, the same in every benchmark."""
    where = "benchmarks/results/ for a configuration kept there, else runs/benchmarks/<derived from the configuration>/"
    parser.add_argument("--out", type=Path, help=f"folder for the results (default: {where})")
    parser.add_argument("--name", help="results file name in that folder (default: the configuration's own)")


def _plain(value: Any) -> Any:
    """A parsed option's value as JSON holds it (paths as text, tuples as lists), so that a recorded configuration
    compares equal to the same one parsed again."""
    return json.loads(json.dumps(value, default=json_default))


def configuration(args: argparse.Namespace, run_options: Iterable[str] = ()) -> dict[str, Any]:
    """The options that decide a run's results: every parsed option but ``--out``, ``--name`` and ``run_options``
    (those that only say how it runs: threads, workers)."""
    skip = OUTPUT_OPTIONS | set(run_options)
    return {k: _plain(v) for k, v in sorted(vars(args).items()) if k not in skip}


def declared(parser: argparse.ArgumentParser, configurations: Mapping[str, Sequence[str]],
             run_options: Iterable[str] = ()) -> dict[str, dict[str, Any]]:  # fmt: skip
    """Each declared configuration's name -> its options, parsed by the benchmark's own parser."""
    return {name: configuration(parser.parse_args(list(argv)), run_options) for name, argv in configurations.items()}


def derived_name(module: str, config: Mapping[str, Any], defaults: Mapping[str, Any]) -> str:
    """A folder name for a configuration kept nowhere: the module's name and each option that differs from its
    default, e.g. ``spine_study_lanes-2_stiffnesses-1`` (a hash where that would be long)."""

    def text(value: Any) -> str:
        items = value if isinstance(value, list) else [value]
        return "-".join(re.sub(r"[^A-Za-z0-9.=+]+", "-", str(v)) for v in items) or "none"

    parts = [f"{k.replace('_', '-')}-{text(v)}" for k, v in config.items() if v != defaults.get(k)]
    name = "_".join([module, *parts])
    if len(name) > 100:
        digest = hashlib.sha1(json.dumps(config, sort_keys=True).encode()).hexdigest()[:12]
        name = f"{module}_{digest}"
    return name


def resolve_output(parser: argparse.ArgumentParser, args: argparse.Namespace, module: str,
                   configurations: Mapping[str, Sequence[str]], files: Sequence[str] = STANDARD_FILES,
                   run_options: Iterable[str] = ()) -> Output:  # fmt: skip
    """Where this run writes, by the rule in this module's docstring; refuses (``parser.error``: one line, exit 2)
    before anything runs when that place holds results of another configuration. ``module`` is the benchmark's
    short name (``spine_study``), ``configurations`` and ``files`` its ``CONFIGURATIONS`` and ``FILES``."""
    run_options = set(run_options)
    config = configuration(args, run_options)
    known = declared(parser, configurations, run_options)
    matches = [name for name, c in known.items() if c == config]
    name = getattr(args, "name", None)
    if name is not None and (not name or Path(name).name != name or name.startswith(".")):
        parser.error(f"--name {name!r}: a file name, without folders")
    out = getattr(args, "out", None)
    if out is None and matches:
        folder = RESULTS
        if name is not None and name not in matches:
            parser.error(f"--name {name}: benchmarks/results/ keeps this configuration as {matches[0]}; give "
                         "--out FOLDER to write it under another name")  # fmt: skip
        name = name or matches[0]
    elif out is None:
        defaults = {k: _plain(parser.get_default(k)) for k in config}
        folder = RUNS / derived_name(module, config, defaults)
        name = name or module
    else:
        folder = Path(out)
        if folder.exists() and not folder.is_dir():
            parser.error(f"--out {folder}: exists and is not a folder")
        name = name or (matches[0] if matches else module)
    kept = folder.resolve() == RESULTS.resolve()
    if kept and name not in matches:
        parser.error(f"--out {folder}: benchmarks/results/ keeps only the configurations {module} declares "
                     f"({', '.join(configurations) or 'none'}), each under its name; give another --out")  # fmt: skip
    problem = parent_problem(folder / name)  # where nothing can be written, refused before the benchmark runs
    if problem:
        parser.error(f"--out {folder}: {problem}")
    output = Output(folder, name, config, kept=kept)
    _refuse_another_configuration(parser, output, files, known)
    return output


def _refuse_another_configuration(parser: argparse.ArgumentParser, output: Output, files: Sequence[str],
                                  known: Mapping[str, dict[str, Any]]) -> None:  # fmt: skip
    if output.kept or not output.folder.is_dir():  # a declared configuration, by resolve_output's own check
        return
    patterns = [f.format(name=output.name) for f in files]
    present = sorted(p.name for p in output.folder.iterdir() if any(fnmatch.fnmatch(p.name, f) for f in patterns))
    if not present:
        return
    recorded = None
    record = output.path(".json")
    if record.is_file():
        try:
            recorded = json.loads(record.read_text()).get("configuration")
        except (OSError, ValueError, AttributeError):
            recorded = None
    if recorded is None and output.folder.resolve() == RESULTS.resolve():
        recorded = known.get(output.name)
    if recorded == output.configuration:
        return
    if recorded is None:
        parser.error(f"{output.folder / present[0]}: holds results whose configuration is not recorded; give "
                     "another --out or --name, or remove them")  # fmt: skip
    differ = sorted(k for k in set(recorded) | set(output.configuration)
                    if recorded.get(k) != output.configuration.get(k))  # fmt: skip
    shown = ", ".join(f"--{k.replace('_', '-')} {recorded.get(k)!r} there, {output.configuration.get(k)!r} here"
                      for k in differ[:3])  # fmt: skip
    parser.error(f"{output.folder / present[0]}: holds the results of another configuration ({shown}); give another "
                 "--out or --name")  # fmt: skip


def claims(name: str, files: Sequence[str] = STANDARD_FILES) -> list[str]:
    """The file-name patterns (``fnmatch``) a benchmark writes for the results name ``name``."""
    return [f.format(name=name) for f in files]


def md_table(header: list[str], rows: list[list[Any]]) -> str:
    def fmt(x: Any) -> str:
        return f"{x:.3g}" if isinstance(x, float) else str(x)

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(x) for x in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"
