"""Shared pieces of the benchmarks: where results go and what machine measured them."""

from __future__ import annotations

import os
import platform
from pathlib import Path
from typing import Any

import mujoco

from envs.common.io import write_json, write_text

RESULTS = Path(__file__).resolve().parent / "results"


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


def save(name: str, result: dict[str, Any], markdown: str, echo: bool = True) -> None:
    """Write ``results/<name>.json`` and ``results/<name>.md`` atomically and (``echo``) print the markdown."""
    write_json(RESULTS / f"{name}.json", {**result, "machine": machine()})
    write_text(RESULTS / f"{name}.md", markdown)
    if echo:
        print(markdown)


def md_table(header: list[str], rows: list[list[Any]]) -> str:
    def fmt(x: Any) -> str:
        return f"{x:.3g}" if isinstance(x, float) else str(x)

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(x) for x in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"
