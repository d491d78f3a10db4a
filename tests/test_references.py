"""Sources are cited by the keys of docs/references.md: every key cited in the docs, the model files and the code's
comments and docstrings is listed there, each listed key is described once, and docs/calibration.md stays a guide
of about 40 KB."""

from __future__ import annotations

import ast
import io
import re
import subprocess
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
REFERENCES = ROOT / "docs" / "references.md"
# a citation: [key] or [key, where]; a key is lowercase, either words joined by hyphens (roach-sim, ax12-manual) or
# a name and a year (haldane2013). Parts of at least two characters, so that a regex class such as [a-z] is no key
KEY = r"[a-z][a-z0-9]+(?:-[a-z0-9]{2,})+|[a-z]+(?:19|20)\d\d"
CITATION = re.compile(rf"\[({KEY})(?:,[^\]\n]*)?\](?!\()")
CALIBRATION_DOC_MOST = 42_000  # bytes: "at most about 40 KB"


def listed_keys() -> list[str]:
    """The keys in the first column of the table at the top of docs/references.md, in order."""
    return re.findall(r"^\| `([^`]+)` \|", REFERENCES.read_text(encoding="utf-8"), flags=re.MULTILINE)


def tracked(*suffixes: str) -> list[Path]:
    """The repository's tracked files with these suffixes (the working tree's, where git is not available)."""
    try:
        names = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
        files = [ROOT / name for name in names.splitlines()]
    except (OSError, subprocess.CalledProcessError):
        files = [p for p in ROOT.rglob("*") if ".git" not in p.parts]
    return sorted(p for p in files if p.suffix in suffixes and p.is_file())


def python_prose(source: str) -> list[tuple[int, str]]:
    """(line, text) of a module's comments and docstrings: where a source is cited, not its code or data strings."""
    prose = [(tok.start[0], tok.string) for tok in tokenize.generate_tokens(io.StringIO(source).readline)
             if tok.type == tokenize.COMMENT]  # fmt: skip
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                if isinstance(body[0].value.value, str):
                    prose += [(body[0].lineno + i, line) for i, line in enumerate(body[0].value.value.splitlines())]
    return prose


def citations(path: Path) -> list[tuple[int, str]]:
    """(line, key) of every citation in a file's prose."""
    text = path.read_text(encoding="utf-8")
    lines = python_prose(text) if path.suffix == ".py" else list(enumerate(text.splitlines(), start=1))
    return [(number, m.group(1)) for number, line in lines for m in CITATION.finditer(line)]


def test_every_key_is_listed_once_and_described():
    keys = listed_keys()
    assert len(keys) >= 3, f"{REFERENCES}: no key table found"
    repeated = sorted({k for k in keys if keys.count(k) > 1})
    assert not repeated, f"{REFERENCES}: keys listed more than once: {', '.join(repeated)}"
    text = REFERENCES.read_text(encoding="utf-8")
    described = re.findall(r"^\*\*`([^`]+)`\*\*", text, flags=re.MULTILINE)
    assert sorted(described) == sorted(keys), (
        f"{REFERENCES}: listed but not described: {sorted(set(keys) - set(described))}; "
        f"described but not listed: {sorted(set(described) - set(keys))}"
    )
    for key in keys:
        assert re.fullmatch(KEY, key), f"{REFERENCES}: key {key!r} is not of the form the citation check reads"


def test_the_three_reports_have_their_keys():
    assert {"roach-sim", "xjus-report", "bioloid-webots"} <= set(listed_keys())


def test_every_cited_key_is_in_the_references():
    known = set(listed_keys())
    unknown = [
        f"{path.relative_to(ROOT)}:{line}: [{key}]"
        for path in tracked(".md", ".xml", ".py")
        for line, key in citations(path)
        if key not in known
    ]
    assert not unknown, "cited keys missing from docs/references.md:\n" + "\n".join(unknown)


@pytest.mark.parametrize(
    "text, keys",
    [
        ("mass 0.030 kg [roach-sim, Table 1]; top speed [haldane2013]", ["roach-sim", "haldane2013"]),
        ("an interval [0.0049, 0.015], a class [a-z], a link [docs](docs/x.md), [low, high]", []),
        ("see [docs-page](https://example.org) and [xjus-report, 2.5]", ["xjus-report"]),
    ],
)
def test_the_citation_pattern_reads_keys_and_nothing_else(text, keys):
    assert [m.group(1) for m in CITATION.finditer(text)] == keys


def test_python_citations_are_read_from_comments_and_docstrings_only():
    source = '"""Model [roach-sim, Table 1]."""\nPATTERN = "[not-a-key]"  # after [ax12-manual]\n'
    found = sorted(key for _, line in python_prose(source) for key in CITATION.findall(line))
    assert found == ["ax12-manual", "roach-sim"]


def test_the_calibration_guide_stays_about_40_kb():
    size = (ROOT / "docs" / "calibration.md").stat().st_size
    assert size <= CALIBRATION_DOC_MOST, f"docs/calibration.md: {size} bytes, more than {CALIBRATION_DOC_MOST}"
