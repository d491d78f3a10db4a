"""No work-log labels anywhere in the repository: every tracked text file (code, tests, docs, results, comments) and
every tracked file name. A label names a work session or an internal document, which means nothing to a user: a
measurement names its conditions (host, date, command) and a source is cited by its key in docs/references.md.

What counts as a label: a session ("stop" and a number, as "stop N", "stop-N", "_stopN", "stops N and M"), a reference
to one of this project's issues ("issue" and a number), a source document by its old number ("seed" and 00N) and the
file of robot notes that is not in the repository (robots .md). Not labels: "stop" and "issue" as words, an option
such as --stop-after, an RNG's "seed 0", a web address (a third-party issue tracker's URL). The real logs under
data/real/ and tests/data/ are third-party files kept verbatim, so they are not read (their READMEs are ours and are).
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
VERBATIM = ("data/real/", "tests/data/")  # third-party logs, kept byte for byte
# each written so that this file does not match itself
LABELS = {
    "session label": re.compile(r"(?<![A-Za-z-])st[o]ps?[ _-]?#?\d+[a-z]?\b", re.IGNORECASE),
    "issue reference": re.compile(r"(?<![A-Za-z/])iss[u]es?[ _-]?#?\d+", re.IGNORECASE),
    "old document number": re.compile(r"(?<![A-Za-z])se[e]ds?[ _-]?00\d\b", re.IGNORECASE),
    "missing notes file": re.compile(r"robots[.]md\b", re.IGNORECASE),
}
URL = re.compile(r"\b[a-z][a-z0-9+.-]*://\S+", re.IGNORECASE)


def tracked() -> list[str]:
    done = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True, timeout=60)
    return [name for name in done.stdout.decode().split("\0") if name]


def labels_in(text: str) -> list[str]:
    """The labels in one line of text (web addresses left out), as found."""
    text = URL.sub(" ", text)
    return [f"{kind} {m.group(0)!r}" for kind, pattern in LABELS.items() for m in pattern.finditer(text)]


def hits() -> list[str]:
    found = []
    for name in tracked():
        found += [f"{name}: file name: {label}" for label in labels_in(name)]
        if name.startswith(VERBATIM) and Path(name).name != "README.md":
            continue
        path = ROOT / name
        if not path.is_file():
            continue
        data = path.read_bytes()
        if b"\0" in data[:8192]:
            continue  # binary (a plot, a frame sheet)
        for number, line in enumerate(data.decode("utf-8", errors="replace").splitlines(), start=1):
            found += [f"{name}:{number}: {label}" for label in labels_in(line)]
    return found


def j(*parts: str) -> str:
    """Text joined from parts, so that this file holds no label itself."""
    return "".join(parts)


def test_the_patterns_find_labels_and_leave_ordinary_words_alone():
    labelled = [
        j("as in st", "op 45"),
        j("(St", "ops 44, 45)"),
        j("calibration_matrix_st", "op27.json"),
        j("the st", "op-30b run"),
        j("Iss", "ue 7's own matrix"),
        j("see iss", "ue #12"),
        j("matrix_iss", "ue7_"),
        j("Se", "ed 002 Figure 30"),
        j("(se", "ed 001, section 2.6)"),
        j("se", "ed002"),
        j("robots", ".md section 3"),
    ]
    for text in labelled:
        assert labels_in(text), text
    ordinary = [
        "--stop-after 5",
        "the loop stops when nothing helps",
        "stop = start + 10",
        "np.arange(0, stop=10)",
        "an issue with the contact model",
        j("https://github.com/google-deepmind/mujoco/iss", "ues/1234"),
        "reset(seed=0), seed 0 and seed 1000",
        "--seed 2",
        "nonstop 24 h",
        "docs/robots.md_like",
    ]
    for text in ordinary:
        assert not labels_in(text), text


def test_no_file_or_file_name_carries_a_work_log_label():
    found = hits()
    by_folder: dict[str, int] = {}
    for hit in found:
        folder = hit.split(":", 1)[0].rsplit("/", 1)[0] if "/" in hit.split(":", 1)[0] else "."
        by_folder[folder] = by_folder.get(folder, 0) + 1
    summary = ", ".join(f"{folder}: {count}" for folder, count in sorted(by_folder.items()))
    shown = "\n".join(found[:200]) + (f"\n... and {len(found) - 200} more" if len(found) > 200 else "")
    assert not found, f"{len(found)} work-log labels ({summary}):\n{shown}"
