"""Atomic file writes: write to a temporary file beside the target, then rename over it."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import signal
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any


def nearest(word: str, choices: Iterable[str], cutoff: float = 0.6) -> str | None:
    """The choice nearest a mistyped ``word`` (``difflib``'s closest match above ``cutoff``), for a message's "did
    you mean"; None if none is near."""
    import difflib

    close = difflib.get_close_matches(word, sorted(choices), n=1, cutoff=cutoff)
    return close[0] if close else None


def not_a_file(path: str | Path, what: str = "file") -> str:
    """Why ``path``, which is not a file, cannot be read as ``what``: ``"a directory, not a <what>"`` or
    ``"no such <what>"``."""
    return f"a directory, not a {what}" if Path(path).is_dir() else f"no such {what}"


def atomic_write(path: str | Path, write: Callable[[Path], None]) -> Path:
    """Call ``write(tmp_path)`` and move the result to ``path`` in one rename, so readers never see half a file."""
    path = Path(path)
    tmp = _written_beside(path, write)
    try:
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def atomic_write_new(path: str | Path, write: Callable[[Path], None]) -> tuple[Path, bool]:
    """:func:`atomic_write` that never replaces a file: the result is linked to ``path`` only if nothing is there
    (an atomic no-clobber, for a ``path`` checked free when the run began). Returns (where the result is, whether
    that is ``path``): if a file appeared at ``path`` meanwhile, it is left as it was and the result stays in its
    temporary file beside it, for the caller to name."""
    path = Path(path)
    tmp = _written_beside(path, write)
    try:
        os.link(tmp, path)
    except FileExistsError:
        return tmp, False
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    tmp.unlink()
    return path, True


def _written_beside(path: Path, write: Callable[[Path], None]) -> Path:
    """A temporary file beside ``path`` (hidden, with the usual permissions) that ``write`` filled; removed if
    ``write`` fails."""
    path.parent.mkdir(parents=True, exist_ok=True)
    prefix, suffix = _temp_affixes(path)
    fd, name = tempfile.mkstemp(prefix=prefix, suffix=suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~current_umask())  # mkstemp makes the file private; give it the usual permissions
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return tmp


def _temp_affixes(path: Path) -> tuple[str, str]:
    """The prefix and suffix of :func:`atomic_write`'s temporary file for ``path``: hidden, and keeping the
    extension, for writers that choose their format by it (ffmpeg, matplotlib)."""
    return f".{path.stem}.", f".tmp{path.suffix}"


# the random part of a name made by tempfile.mkstemp/mkdtemp: 8 characters of tempfile._RandomNameSequence
TEMP_RANDOM = "[a-z0-9_]{8}"


def atomic_write_leftovers(folder: str | Path, names: Iterable[str]) -> list[Path]:
    """The temporary files :func:`atomic_write` left in ``folder`` when it was killed while writing one of the files
    ``names`` (e.g. ``model.zip``: ``.model.<8 random characters>.tmp.zip``). Only these exact names: a user's
    look-alike such as ``.notes.tmp.txt`` is not one."""
    folder = Path(folder)
    patterns = [
        re.compile(re.escape(prefix) + TEMP_RANDOM + re.escape(suffix))
        for prefix, suffix in (_temp_affixes(folder / name) for name in names)
    ]
    return sorted(
        path
        for path in (folder.iterdir() if folder.is_dir() else ())
        if path.is_file() and not path.is_symlink() and any(p.fullmatch(path.name) for p in patterns)
    )


def current_umask() -> int:
    """The process's umask (read by setting it and setting it back)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text(path: str | Path, text: str) -> Path:
    return atomic_write(path, lambda p: p.write_text(text))


def write_json(path: str | Path, obj: Any, strict: bool = False) -> Path:
    """``obj`` as JSON at ``path``, atomically. ``strict``: every NaN or infinite number is written as null
    (:func:`finite_json`), so that strict readers (JavaScript's ``JSON.parse``) take the file."""
    if strict:
        text = json.dumps(finite_json(obj), indent=2, allow_nan=False)
    else:
        text = json.dumps(obj, indent=2, sort_keys=False, default=json_default)
    return write_text(path, text + "\n")


def finite_json(value: Any) -> Any:
    """``value`` as plain JSON values (numpy scalars and arrays, paths converted), every NaN or infinite number as
    None: JSON has no NaN, and the bare ``NaN`` Python's ``json`` writes by default is refused by strict readers."""
    import math

    import numpy as np

    if isinstance(value, dict):
        return {key: finite_json(item) for key, item in value.items()}
    if isinstance(value, list | tuple | np.ndarray):
        return [finite_json(item) for item in value]
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, Path):
        return str(value)
    return value


def json_default(obj: Any) -> Any:
    """``json.dumps`` default for numpy scalars and arrays and paths."""
    import numpy as np

    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot write {type(obj).__name__} as JSON")


def publish_folder(
    tmp: str | Path, out: str | Path, existed: bool = True, foreign: Callable[[Path], list[str]] | None = None
) -> Path:
    """Put a finished folder in place of ``out`` by renames; an earlier ``out`` goes only once the new one is in.
    Returns where the folder went.

    ``out`` was checked when the run began (:func:`results_folder_problem`); ``existed`` says whether it was there
    then. If it has appeared since, or now holds an entry ``foreign`` names (files the tool does not write, put there
    during the run), it is left alone and the folder goes to the first free ``out-2``, ``out-3``, ...: never a
    silent overwrite, and the run's results are not lost. The caller says so."""
    import shutil

    tmp, out = Path(tmp), Path(out)
    if out.exists():
        changed = not existed or not out.is_dir()
        if not changed and foreign is not None:
            changed = any(foreign(entry) for entry in out.iterdir())
        if changed:
            for k in range(2, 10_000):
                target = out.with_name(f"{out.name}-{k}")
                if not target.exists():
                    try:
                        os.rename(tmp, target)  # onto a name that does not exist (an empty folder made meanwhile
                        # would be taken: os.rename replaces only an empty one)
                    except OSError:
                        continue
                    return target
            raise FileExistsError(f"{out}-2 to {out}-9999 all exist")
        old = out.with_name(f".{out.name}.old-{os.getpid()}")
        os.replace(out, old)
        try:
            os.replace(tmp, out)
        except OSError:
            os.replace(old, out)  # the earlier results go back in place; the caller keeps the new ones elsewhere
            raise
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(tmp, out)
    return out


def refuse_overwrite(path: str | Path, what: str = "file") -> Path:
    """Raise a clear error if ``path`` exists: we never overwrite a user's file silently."""
    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{what} {path} already exists; choose another path or remove it first")
    return path


def parent_problem(path: str | Path, probe: str = ".probe-") -> str | None:
    """Why nothing can be created at ``path`` (its nearest existing ancestor a file, or no folder can be made in it),
    or None. Tried with a probe folder named ``probe`` + 8 random characters, removed at once: a permission check
    alone passes for root even in /proc."""
    parent = Path(path).parent
    while not parent.exists():  # ends at "." or "/"
        parent = parent.parent
    if not parent.is_dir():
        return f"{parent} is a file, not a directory"
    try:
        os.rmdir(tempfile.mkdtemp(prefix=probe, dir=parent))
    except OSError as exc:
        return f"cannot create folders in {parent} ({exc.strerror})"
    return None


def results_foreign(out: str | Path, files: Sequence[str], folders: Mapping[str, str]) -> Callable[[Path], list[str]]:
    """What in an entry of ``out`` a results tool does not write (as paths within ``out``), for
    :func:`results_folder_problem` and :func:`publish_folder`: the tool writes ``files`` and, in each of
    ``folders``, files of its suffix (folder -> suffix). A folder without the tool's ``files[0]`` holds no earlier
    run, so all of it is the user's."""
    out = Path(out)
    earlier = (out / files[0]).is_file()

    def foreign(entry: Path) -> list[str]:
        if earlier and entry.name in files and entry.is_file():
            return []
        suffix = folders.get(entry.name)
        if not earlier or suffix is None or not entry.is_dir():
            return [entry.name + "/" * entry.is_dir()]
        return [f"{entry.name}/{f.name}" for f in sorted(entry.iterdir()) if not (f.is_file() and f.suffix == suffix)]

    return foreign


def current_folder_problem(out: str | Path, flag: str = "--out") -> str | None:
    """Why ``out`` cannot be a tool's own folder, or None: it is empty, ``.`` or a root, or the current folder or
    one that holds it (the tool would write among, or replace, the user's files)."""
    given, out = str(out), Path(out)
    if not out.name or out.resolve() in (Path.cwd(), *Path.cwd().parents):
        return f"{flag} {given!r} is the current folder or holds it; give the name of a folder for the results"
    return None


def results_folder_problem(
    out: str | Path, overwrite: bool, tool: str, foreign: Callable[[Path], list[str]], flag: str = "--out"
) -> str | None:
    """Why a tool's results (a folder it replaces whole, :func:`publish_folder`) cannot go to ``out``, or None.
    ``foreign(entry)`` names what in an entry of ``out`` the tool does not write: a folder holding any such file is
    refused even with ``overwrite`` (replacing it would delete the user's files); one holding an earlier run's
    results only with ``overwrite``. Checked before anything is computed."""
    out = Path(out)
    problem = current_folder_problem(out, flag)
    if problem:
        return problem
    if out.is_dir():
        held = sorted(out.iterdir())
        others = [name for entry in held for name in foreign(entry)]
        if others:
            shown = ", ".join(others[:5]) + (f" and {len(others) - 5} more" if len(others) > 5 else "")
            return (f"{flag} {out} holds files {tool} does not write ({shown}); it replaces the whole folder, so this "
                    "is refused even with --overwrite: choose another directory or move them")  # fmt: skip
        if held and not overwrite:
            names = ", ".join(entry.name + "/" * entry.is_dir() for entry in held)
            return f"{flag} {out} already holds {names} of an earlier run; choose another directory or pass --overwrite"
    elif out.exists():
        return f"{flag} {out} exists and is not a directory"
    problem = parent_problem(out)
    return f"{flag} {out}: {problem}" if problem else None


def replace_problem(out: str | Path, flag: str = "--out") -> str | None:
    """Why :func:`publish_folder` could not put a finished folder in place of ``out``, or None: ``out`` is a mount
    point (which no rename moves), or the folders it makes beside ``out`` (``.<name>.<8 random>`` to stage the
    results, ``.<name>.old-<pid>`` for the folder it replaces) cannot be made there, e.g. a name near the file
    system's length limit. Tried with a probe folder of the longer name, removed at once; checked before anything is
    computed, after :func:`results_folder_problem`."""
    out = Path(out)
    if out.is_dir() and os.path.ismount(out):
        return f"{flag} {out} is a mount point, which cannot be replaced; give a folder inside it"
    problem = parent_problem(out, probe=f".{out.name}.old-")  # the longest name it makes beside ``out``
    if problem:
        return f"{flag} {out}: the folders that stage and replace it cannot be made beside it: {problem}"
    return None


def keep_unpublished(staging: str | Path, out: str | Path) -> Path | None:
    """Keep a finished folder that :func:`publish_folder` could not put at ``out``: moved to a new folder of its own
    beside ``out`` (``<name>.unpublished-<8 random>``), else in the system's temporary folder. Returns where it is,
    or None if neither could take it."""
    import shutil

    staging, out = Path(staging), Path(out)
    for parent in (out.parent, Path(tempfile.gettempdir())):
        try:
            kept = Path(tempfile.mkdtemp(prefix=f"{out.name[:100]}.unpublished-", dir=parent))
            try:
                os.replace(staging, kept)  # onto the empty folder just made
            except OSError:  # the system's temporary folder may be on another file system
                shutil.copytree(staging, kept, dirs_exist_ok=True)
            os.chmod(kept, 0o777 & ~current_umask())
            return kept
        except OSError:
            if "kept" in locals():
                shutil.rmtree(kept, ignore_errors=True)  # no half-copied folder left behind
            continue
    return None


def unpublished_exit_code(tool: str, staging: str | Path, out: str | Path, exc: OSError) -> int:
    """:func:`publish_folder` could not put a results tool's finished folder at ``out``: kept elsewhere
    (:func:`keep_unpublished`) and said where, in one line; exit code 1."""
    kept = keep_unpublished(staging, out)
    where = f"they are kept in {kept}/" if kept else "nowhere could keep them"
    print(f"{tool}: error: cannot put the results at {out} ({exc.strerror or exc}); {where}", file=sys.stderr)
    return 1


def foreign_unless(names: tuple[str, ...]) -> Callable[[Path], list[str]]:
    """For :func:`results_folder_problem`: every entry but the files ``names`` is foreign."""
    return lambda entry: [] if entry.name in names and entry.is_file() else [entry.name + "/" * entry.is_dir()]


class DuplicateKey(ValueError):
    """A JSON object gives one key twice (the key is the error's argument)."""


def unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``json.loads``' ``object_pairs_hook``: a JSON object's pairs as a dict, refusing a key given twice
    (:class:`DuplicateKey`; json keeps the last silently)."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise DuplicateKey(key)
        out[key] = value
    return out


def json_object(text: str, flag: str) -> dict[str, Any]:
    """A command line's JSON object of keyword arguments (the value of ``flag``, e.g. ``--env-kwargs``); ValueError
    names the flag and the value."""
    try:
        value = json.loads(text)
    except ValueError as exc:
        raise ValueError(f"{flag} {text!r}: not JSON ({exc})") from None
    if not isinstance(value, dict):
        raise ValueError(f"{flag} {text!r}: expected a JSON object of keyword arguments")
    return value


def _whole_number(text: str, least: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= {least}, got {text!r}") from None
    if value < least:
        raise argparse.ArgumentTypeError(f"expected a whole number >= {least}, got {value}")
    return value


def at_least_one(text: str) -> int:
    """An argparse type: a whole number of at least 1 (steps, rounds, episodes, simulations)."""
    return _whole_number(text, 1)


def non_negative(text: str) -> int:
    """An argparse type: a whole number of at least 0 (a seed, as numpy takes it; a number of extra draws)."""
    return _whole_number(text, 0)


def positive_number(text: str) -> float:
    """An argparse type: a finite number above 0 (seconds, frequencies)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}") from None
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text}")
    return value


class ToolParser(argparse.ArgumentParser):
    """The command-line parser of every skitter tool: a bad argument is one line, ``PROG: error: ... (see --help)``,
    and exit code 2, without argparse's usage block. A ``description`` is a module's docstring: ``--help`` shows its
    first paragraph, whole (its first line alone stops mid-sentence). An ``epilog`` that is the same docstring shows
    the rest of it, after that paragraph."""

    def __init__(self, *args: Any, description: str | None = None, **kwargs: Any):
        if description:
            first, _, rest = description.strip().partition("\n\n")
            if kwargs.get("epilog") == description:
                kwargs["epilog"] = rest.strip() or None
            description = " ".join(first.split())
        super().__init__(*args, description=description, **kwargs)

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


class Terminated(KeyboardInterrupt):
    """SIGTERM (``kill``, a job scheduler's time limit), raised like Ctrl-C's KeyboardInterrupt so that a tool's
    ``finally`` clauses run: a temporary folder is removed, a checkpoint saved (:func:`sigterm_as_interrupt`)."""


def _raise_terminated(signum: int, frame) -> None:
    raise Terminated


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM raises :class:`Terminated` (the default would end the process at once, leaving
    temporary files behind); the handler before is restored after."""
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def interrupted_exit_code(exc: KeyboardInterrupt) -> int:
    """The shell's exit code for a process ended by SIGTERM (143) or Ctrl-C (130)."""
    return 128 + (signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT)


def run_interruptibly(tool: str, out: Path, run: Callable[[], int]) -> int:
    """A results tool's ``main``: ``run()`` with SIGTERM raised like Ctrl-C (its staging folder removed on the way
    out), an interruption reported in one line with the shell's exit code (130 or 143)."""
    try:
        with sigterm_as_interrupt():
            return run()
    except KeyboardInterrupt as exc:
        print(f"{tool}: interrupted; {out} is as it was", file=sys.stderr)
        return interrupted_exit_code(exc)


def published_exit_code(tool: str, out: Path, where: Path) -> int:
    """0 when :func:`publish_folder` put the results at ``out``; else, said in one line, 1: ``out`` appeared or took
    files the tool does not write during the run and was left as it is."""
    if where == out:
        return 0
    print(f"{tool}: error: {out} appeared or took files {tool} does not write during the run; it is left as it is, "
          f"and the results are in {where}/", file=sys.stderr)  # fmt: skip
    return 1


class Busy(RuntimeError):
    """Another process holds the lock of a folder that one process at a time may write (:func:`folder_lock`)."""


@contextlib.contextmanager
def folder_lock(folder: str | Path, tool: str, lock_name: str = ".lock", wait: bool = False) -> Iterator[Path]:
    """Hold an exclusive lock on ``folder`` (an ``fcntl.flock`` on the file ``folder/lock_name``, made if missing) for
    the block, so that two runs of a tool never write one folder at once. A second process gets :class:`Busy` at once,
    with a message naming the folder, or with ``wait`` says that it waits and waits for the lock (for work that two
    runs share, such as a table both write). The kernel drops the lock when the process ends, however
    it ends, so a killed run never leaves the folder locked; the lock file itself stays (removing it would let a third
    process lock a new file while the second still holds the old one)."""
    import fcntl

    path = Path(folder) / lock_name
    path.parent.mkdir(parents=True, exist_ok=True)
    handle = open(path, "a+")  # held for the block
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if not wait:
                raise Busy(f"{tool}: {Path(folder)} is in use by another {tool} run (lock {path}); wait for it to "
                           "end, or choose another folder") from None  # fmt: skip
            print(f"{tool}: waiting for another {tool} run to finish with {Path(folder)} (lock {path})",
                  file=sys.stderr, flush=True)  # fmt: skip
            fcntl.flock(handle, fcntl.LOCK_EX)
        yield path
    finally:
        handle.close()


# --- progress in a log file -------------------------------------------------------------------------------------
PROGRESS_SECONDS = 60.0  # wall time between two lines of :class:`ProgressLines`


class ProgressLines:
    """A long command's progress as a line every ``seconds`` (default :data:`PROGRESS_SECONDS`) of wall time, for
    output that is no terminal (``nohup``, a log file), where a progress bar would be one line redrawn: ``step 120,000
    of 4,000,000 (3%), 620 steps/s, 1 h 44 min left (ends about 16:49)``, and what the tool adds. The rate is over
    this process's work (a resumed run's earlier work is not in it)."""

    def __init__(self, total: int, unit: str = "step", seconds: float | None = None):
        self.total, self.unit = int(total), unit
        self.seconds = PROGRESS_SECONDS if seconds is None else float(seconds)
        self._start: float | None = None
        self._done_at_start = 0

    def start(self, done: int) -> None:
        """Begin timing at ``done`` of the total."""
        import time

        self._start = self._last = time.monotonic()
        self._done_at_start = int(done)

    def update(self, done: int, extra: str = "") -> str | None:
        """Print (and return) the line if ``seconds`` have passed since the last one."""
        import time

        now = time.monotonic()
        if self._start is None:
            self.start(done)
            return None
        if now - self._last < self.seconds:
            return None
        self._last = now
        line = self.line(done, now - self._start) + (f", {extra}" if extra else "")
        print(line, flush=True)
        return line

    def line(self, done: int, elapsed: float) -> str:
        """The line after ``elapsed`` seconds of this process's work, at ``done`` of the total."""
        import time

        rate = (done - self._done_at_start) / elapsed if elapsed > 0 else 0.0
        per = f"{rate:.0f} {self.unit}s/s" if rate >= 10 else f"{rate * 60:.3g} {self.unit}s/min"
        text = f"{self.unit} {done:,} of {self.total:,} ({100.0 * done / max(self.total, 1):.0f}%), {per}"
        if rate > 0 and done < self.total:
            left = (self.total - done) / rate
            ends = time.strftime("%H:%M", time.localtime(time.time() + left))
            text += f", {duration_text(left)} left (ends about {ends})"
        return text


def duration_text(seconds: float) -> str:
    """``seconds`` as ``1 h 05 min`` or ``7 min``."""
    minutes = round(seconds / 60.0)
    return f"{minutes // 60} h {minutes % 60:02d} min" if minutes >= 60 else f"{minutes} min"


def progress_bar_wanted(no_progress: bool) -> bool:
    """Whether a command shows a progress bar: on a terminal, unless ``--no-progress``; elsewhere (a log file)
    :class:`ProgressLines` takes its place."""
    return not no_progress and sys.stdout.isatty()
