"""benchmarks/results/ holds the current output of each benchmark and configuration, each file written by the module
its name names; a benchmark writes to the folder of its configuration and never over another configuration's results
(benchmarks/common.py)."""

from __future__ import annotations

import argparse
import fnmatch
import hashlib
import importlib
import json
import os
import pkgutil
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

import benchmarks
from benchmarks import common
from envs.common import host, io

RESULTS = Path(__file__).resolve().parents[1] / "benchmarks" / "results"


def benchmark_modules() -> list[ModuleType]:
    """Every module under benchmarks/ that runs as a command (has a ``main``)."""
    found = []
    for info in pkgutil.iter_modules(benchmarks.__path__):
        module = importlib.import_module(f"benchmarks.{info.name}")
        if hasattr(module, "main"):
            found.append(module)
    return found


def claims() -> dict[str, list[tuple[str, str]]]:
    """Each file-name pattern -> the (module, configuration name) pairs that write it."""
    out: dict[str, list[tuple[str, str]]] = {}
    for module in benchmark_modules():
        files = getattr(module, "FILES", common.STANDARD_FILES)
        for name in module.CONFIGURATIONS:
            for pattern in common.claims(name, files):
                out.setdefault(pattern, []).append((module.__name__, name))
    return out


def test_every_benchmark_declares_the_configurations_it_keeps():
    modules = benchmark_modules()
    assert len(modules) >= 18
    undeclared = [m.__name__ for m in modules if not isinstance(getattr(m, "CONFIGURATIONS", None), dict)]
    assert not undeclared, f"benchmarks without CONFIGURATIONS: {undeclared}"


def test_every_results_file_maps_to_one_benchmark_module_and_configuration():
    patterns = claims()
    unclaimed, twice = [], []
    for path in sorted(RESULTS.iterdir()):
        owners = {owner for pattern, who in patterns.items() if fnmatch.fnmatch(path.name, pattern) for owner in who}
        if not owners:
            unclaimed.append(path.name)
        elif len({module for module, _ in owners}) > 1:
            twice.append((path.name, sorted(owners)))
    assert not unclaimed, f"files in benchmarks/results/ that no benchmark module writes: {unclaimed}"
    assert not twice, f"files claimed by more than one module: {twice}"


@pytest.mark.parametrize("module", benchmark_modules(), ids=lambda m: m.__name__.split(".")[-1])
def test_each_declared_configuration_parses_differs_and_has_its_results(module):
    """A declared configuration is one the module's own parser accepts, no two names hold the same one, and its
    results are in benchmarks/results/ (the JSON and the Markdown at least, and a file for every pattern)."""
    if not module.CONFIGURATIONS:
        return
    parser = module.make_parser()
    run_options = getattr(module, "RUN_OPTIONS", ())
    known = common.declared(parser, module.CONFIGURATIONS, run_options)
    configs = [json.dumps(c, sort_keys=True) for c in known.values()]
    assert len(set(configs)) == len(configs), f"{module.__name__}: two names for one configuration"
    present = [p.name for p in RESULTS.iterdir()]
    for name in module.CONFIGURATIONS:
        for pattern in common.claims(name, getattr(module, "FILES", common.STANDARD_FILES)):
            assert fnmatch.filter(present, pattern), f"{module.__name__}: {name}: no file {pattern} in results"
    for name, config in known.items():  # a recorded configuration is the declared one
        recorded = json.loads((RESULTS / f"{name}.json").read_text()).get("configuration")
        assert recorded in (None, config), name


# the rule itself, on a stand-in benchmark


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="toy")
    parser.add_argument("--size", type=int, default=3)
    parser.add_argument("--mode", choices=["a", "b"], default="a")
    parser.add_argument("--threads", type=int, default=1)
    common.add_output_options(parser)
    return parser


TOY = {"toy": [], "toy_b": ["--mode", "b"]}


def _resolve(argv: list[str]) -> common.Output:
    parser = _parser()
    return common.resolve_output(parser, parser.parse_args(argv), "toy", TOY, run_options=("threads",))


@pytest.fixture
def toy(tmp_path, monkeypatch):
    monkeypatch.setattr(common, "RESULTS", tmp_path / "results")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(common, "machine", lambda: {})
    return tmp_path


def test_a_declared_configuration_writes_its_kept_results_and_another_its_own_folder(toy):
    assert _resolve([]).folder == toy / "results" and _resolve([]).name == "toy"
    assert _resolve(["--mode", "b", "--threads", "2"]).name == "toy_b"  # threads: how it runs, not what
    assert _resolve(["--mode", "b"]).kept
    other = _resolve(["--size", "1"])
    assert not other.kept
    assert other.folder == Path("runs/benchmarks/toy_size-1") and other.name == "toy"
    assert _resolve(["--size", "1", "--out", "x"]).folder == Path("x")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--name", "toy_b"], "keeps this configuration as toy"),
        (["--name", "a/b"], "a file name, without folders"),
        (["--size", "1", "--out", "results"], "keeps only the configurations toy declares"),
    ],
)
def test_writing_under_another_configurations_name_is_refused(toy, capsys, argv, message):
    with pytest.raises(SystemExit) as exit_info:
        _resolve(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_an_out_folder_nothing_can_be_written_in_is_refused_before_the_benchmark_runs(toy, capsys):
    (toy / "afile").write_text("a user's file")
    with pytest.raises(SystemExit) as exit_info:
        _resolve(["--out", "afile/results"])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and "--out afile/results: " in err and "is a file, not a directory" in err
    assert (toy / "afile").read_text() == "a user's file"


@pytest.mark.parametrize(
    ("kind", "text", "message"),
    [
        (io.at_least_one, "0", "a whole number >= 1, got 0"),
        (io.at_least_one, "-5", "a whole number >= 1, got -5"),
        (io.at_least_one, "x", "a whole number >= 1, got 'x'"),
        (io.non_negative, "-1", "a whole number >= 0, got -1"),
        (io.positive_number, "nan", "a finite number > 0, got nan"),
        (io.positive_number, "0", "a finite number > 0, got 0"),
    ],
)
def test_counts_seeds_and_durations_of_a_benchmark_are_checked_as_parsed(kind, text, message, capsys):
    parser = argparse.ArgumentParser(prog="toy")
    parser.add_argument("--value", type=kind)
    with pytest.raises(SystemExit) as exit_info:
        parser.parse_args(["--value", text])
    assert exit_info.value.code == 2 and f"argument --value: expected {message}" in capsys.readouterr().err
    assert parser.parse_args(["--value", "3"]).value == 3


def test_a_folder_with_another_configurations_results_is_refused_before_anything_runs(toy, capsys):
    out = _resolve(["--size", "1", "--out", "x"])
    out.save({"value": 1}, "# one\n", echo=False)
    assert json.loads((toy / "x" / "toy.json").read_text())["configuration"] == {"mode": "a", "size": 1}
    _resolve(["--size", "1", "--out", "x", "--threads", "4"]).save({"value": 2}, "# two\n", echo=False)  # its own
    with pytest.raises(SystemExit):
        _resolve(["--size", "2", "--out", "x"])
    err = capsys.readouterr().err
    assert "x/toy.json: holds the results of another configuration (--size 1 there, 2 here)" in err
    assert json.loads((toy / "x" / "toy.json").read_text())["value"] == 2
    (toy / "y").mkdir()
    (toy / "y" / "toy.md").write_text("# by hand\n")
    with pytest.raises(SystemExit):
        _resolve(["--out", "y"])
    assert "configuration is not recorded" in capsys.readouterr().err
    # the kept results: their configuration is the declared one, recorded or not
    (toy / "results").mkdir()
    (toy / "results" / "toy_b.json").write_text("{}")
    assert _resolve(["--mode", "b"]).name == "toy_b"
    with pytest.raises(SystemExit):
        _resolve(["--size", "5", "--out", "results", "--name", "toy_b"])


def _digest(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


@pytest.mark.filterwarnings("ignore:Degrees of freedom")  # episodes shorter than the settling second
def test_a_tiny_spine_study_leaves_the_committed_study_alone(tmp_path, monkeypatch, capsys):
    """The spine study with fewer lanes and stiffnesses writes under a folder named by its configuration (or the
    --out given), never over the committed 840-episode results; a folder holding another configuration's study is
    refused in one line before any episode runs."""
    from benchmarks import spine_study

    before = _digest(RESULTS)
    monkeypatch.chdir(tmp_path)
    tiny = ["--lanes", "1", "--stiffnesses", "1", "--roughness", "0", "--obstacles", "--seconds", "0.1"]
    tiny += ["--threads", "1"]
    spine_study.main(tiny)
    derived = "spine_study_lanes-1_obstacles-none_roughness-0.0_seconds-0.1_stiffnesses-1"
    folder = tmp_path / "runs" / "benchmarks" / derived
    assert sorted(p.name for p in folder.iterdir()) == ["spine_study.json", "spine_study.md", "spine_study.png"]
    assert json.loads((folder / "spine_study.json").read_text())["configuration"]["lanes"] == 1
    assert _digest(RESULTS) == before
    capsys.readouterr()
    for argv, message in (
        ([*tiny, "--out", str(RESULTS)], "keeps only the configurations spine_study declares"),
        (["--name", "spine_study_constant_damping"], "keeps this configuration as spine_study"),
        ([*tiny[:-2], "--out", str(folder)], None),  # the same configuration again: its own folder, rewritten
        ([*tiny, "--lanes", "2", "--out", str(folder)], "holds the results of another configuration (--lanes 1"),
    ):
        if message is None:
            spine_study.main(argv)
            continue
        with pytest.raises(SystemExit) as exit_info:
            spine_study.main(argv)
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err, err
    assert _digest(RESULTS) == before


def test_the_cpg_summary_does_not_replace_kept_runs_it_cannot_see(tmp_path, monkeypatch, capsys):
    """The CPG experiments' summary reads run folders that a fresh checkout does not hold: run there, it refuses to
    replace the kept results (which summarize runs) with "not run yet", and writes nothing."""
    from benchmarks import bioloid_cpg_experiments as cpg

    kept = Path(cpg.__file__).parent / "results" / "bioloid_cpg_experiments.json"
    folder = tmp_path / "results"
    folder.mkdir()
    argv = ["--out", str(folder), "--name", "bioloid_cpg_experiments"]
    settings = common.configuration(cpg.make_parser().parse_args(argv))
    recorded = {**json.loads(kept.read_text()), "configuration": settings}
    (folder / kept.name).write_text(json.dumps(recorded))
    monkeypatch.setattr(cpg, "ROOT", tmp_path)  # no runs/optimize/ there
    with pytest.raises(SystemExit) as exit_:
        cpg.main(argv)
    assert exit_.value.code == 1
    assert "experiment 5, experiment 6, whose run folders are not here: nothing written" in capsys.readouterr().err
    assert sorted(p.name for p in folder.iterdir()) == [kept.name]
    assert json.loads((folder / kept.name).read_text()) == recorded


def test_a_result_names_the_cpu_code_paths_its_numbers_came_from():
    """numpy picks its functions' SIMD code at run time, and the paths differ in the last bit: a result keeps them."""
    found = common.machine()
    assert found["numpy_simd"] == host.numpy_simd() and found["cpu"] == host.cpu_name()
    # the same host told to leave out AVX-512 runs other paths, and says so
    code = "from envs.common.host import numpy_simd; print(numpy_simd())"
    env = {**os.environ, "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"}
    without = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert "X86_V4" not in without.stdout.split() and "baseline" in without.stdout
