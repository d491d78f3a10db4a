"""The layers read one way: no import cycle between modules (imports inside functions count), and the import-linter
contracts of pyproject.toml (``[tool.importlinter]``: benchmarks > sysid > agents > envs > assets; in envs the robots
> actuators > common; no robot importing another's modules) all kept. And imports say what they bring: no
one-letter alias."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import grimp
import numpy as np
import pytest
from scipy.sparse import csr_array
from scipy.sparse.csgraph import connected_components

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "pyproject.toml"
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


def root_packages() -> list[str]:
    return tomllib.loads(CONFIG.read_text())["tool"]["importlinter"]["root_packages"]


def import_cycles(packages: list[str]) -> list[list[str]]:
    """The import cycles between modules of ``packages``: each strongly connected component of the module import
    graph (grimp's: imports inside functions and under ``TYPE_CHECKING`` count) with more than one module, sorted."""
    graph = grimp.build_graph(*packages, cache_dir=None)
    modules = sorted(graph.modules)
    index = {name: i for i, name in enumerate(modules)}
    edges = [(index[a], index[b]) for a in modules for b in graph.find_modules_directly_imported_by(a)]
    rows, cols = np.array(edges, dtype=int).reshape(-1, 2).T
    adjacency = csr_array((np.ones(len(rows)), (rows, cols)), shape=(len(modules), len(modules)))
    _, labels = connected_components(adjacency, directed=True, connection="strong")
    groups: dict[int, list[str]] = {}
    for name, label in zip(modules, labels, strict=True):
        groups.setdefault(int(label), []).append(name)
    return sorted(group for group in groups.values() if len(group) > 1)


def describe(cycles: list[list[str]], packages: list[str]) -> str:
    """Each cycle's modules and the import lines that join them."""
    graph = grimp.build_graph(*packages, cache_dir=None)
    out = []
    for group in cycles:
        members = set(group)
        lines = [
            f"    {d['importer']}:{d['line_number']} imports {d['imported']} ({d['line_contents']})"
            for a in group
            for b in sorted(graph.find_modules_directly_imported_by(a) & members)
            for d in graph.get_import_details(importer=a, imported=b)
        ]
        out.append(f"cycle between {', '.join(group)}:\n" + "\n".join(lines))
    return "\n".join(out)


def lint_imports(config: Path, cwd: Path) -> subprocess.CompletedProcess:
    """import-linter's command on ``config``, run from ``cwd`` (which it puts on the path), without a cache."""
    env = {**os.environ, "PYTHONPATH": str(cwd)}
    return subprocess.run([str(LINT_IMPORTS), "--no-cache", str(config)], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300)  # fmt: skip


def test_no_import_cycle_between_modules():
    packages = root_packages()
    cycles = import_cycles(packages)
    assert not cycles, describe(cycles, packages)


def test_the_cycle_finder_sees_a_cycle_hidden_inside_a_function(tmp_path, monkeypatch):
    """The check above finds a cycle closed by an import inside a function (and names its modules)."""
    package = tmp_path / "looped"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "low.py").write_text("def f():\n    from looped.high import g\n\n    return g\n")
    (package / "high.py").write_text("from looped.low import f\n\n\ndef g():\n    return f\n")
    (package / "apart.py").write_text("import looped.low\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    cycles = import_cycles(["looped"])
    assert cycles == [["looped.high", "looped.low"]]
    assert "looped.low:2 imports looped.high" in describe(cycles, ["looped"])


def test_the_import_contracts_are_kept():
    assert LINT_IMPORTS.exists(), f"{LINT_IMPORTS} is missing: install the dev extra (import-linter)"
    contracts = tomllib.loads(CONFIG.read_text())["tool"]["importlinter"]["contracts"]
    assert {c["type"] for c in contracts} >= {"layers", "forbidden"}
    result = lint_imports(CONFIG, ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"Contracts: {len(contracts)} kept, 0 broken." in result.stdout, result.stdout


@pytest.mark.parametrize("where", ["top", "function"])
def test_a_broken_layer_contract_fails(tmp_path, where):
    """import-linter refuses a lower layer importing a higher one, at the top of a module or inside a function."""
    for name in ("upper", "lower"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text("")
    (tmp_path / "upper" / "a.py").write_text("import lower.b\n")
    body = "import upper.a\n" if where == "top" else "def f():\n    import upper.a\n\n    return upper.a\n"
    (tmp_path / "lower" / "b.py").write_text(body)
    config = tmp_path / "contracts.toml"
    config.write_text(
        textwrap.dedent("""
            [tool.importlinter]
            root_packages = ["upper", "lower"]

            [[tool.importlinter.contracts]]
            name = "upper above lower"
            type = "layers"
            layers = ["upper", "lower"]
        """)
    )
    result = lint_imports(config, tmp_path)
    assert result.returncode != 0, result.stdout
    assert "upper above lower BROKEN" in result.stdout and "lower.b -> upper.a" in result.stdout, result.stdout


def test_no_import_takes_a_one_letter_alias():
    """``from envs.xjus import constants as C`` reads as a riddle where it is used: import the names, or the module
    by its name."""
    found = []
    skipped = {".venv", ".git", "build", "runs", "results"}
    paths = []
    for folder, subfolders, files in os.walk(ROOT):
        # the project's own files: not a virtualenv, git's store, a build, nor the runs' and results' output folders
        # (a benchmark keeps dm_control's virtualenv in runs/), which are not walked into at all
        subfolders[:] = [d for d in subfolders if d not in skipped]
        paths += [Path(folder) / f for f in files if f.endswith(".py")]
    for path in sorted(paths):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import | ast.ImportFrom):
                found += [f"{path.relative_to(ROOT)}:{node.lineno}: {a.name} as {a.asname}"
                          for a in node.names if a.asname is not None and len(a.asname) == 1]  # fmt: skip
    assert not found, "\n".join(found)
