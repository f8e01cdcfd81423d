"""One command at a time per output folder: the lock file ``FOLDER/.pmsmjax.lock``.

Two commands writing one folder at once (two ``pmsmjax montecarlo --out runs`` with different seeds) would
mix their chunks, checkpoints and summaries. A command that writes a folder therefore first creates the
lock file atomically (``os.open`` with ``O_CREAT | O_EXCL``: of two commands exactly one succeeds) holding
JSON ``{"pid", "host", "argv", "time"}``, and removes it when it ends, however it ends. A second command
finding the lock is refused with one line naming the first (its command line, pid, host, start time).

A lock left by a command that died without removing it (killed, power cut) is *stale*: its pid no longer runs
on this host. A stale lock is taken over with a warning, and the dead command's temporary files
(`orphan_temporaries`: the ``.NAME.XXXXXXXX.tmp`` files of [`atomic_write`][pmsmjax.io.logs.atomic_write], in
the folder and its sub-folders, matched by that pattern only) are removed: files being written when it died,
never finished, and as large as the trace they were to become. Who takes it over is decided by a second atomic
file, ``FOLDER/.pmsmjax.lock.break``, so two commands finding the same stale lock cannot both proceed. A lock
written on another host cannot be checked from here and is always refused (the message says which file to
delete if that command is known to be gone); so is a lock whose content cannot be read (it is being written,
or is not ours) unless it is older than `UNREADABLE_STALE_S`.

Pure Python (no JAX): `pmsmjax.cli.main` takes the lock right after parsing the flags, before the
command checks or writes anything.
"""

import contextlib
import json
import os
import re
import socket
import time
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path

from pmsmjax.spec.validation import ParameterError

__all__ = [
    "LOCK_NAME",
    "TEMP_PREFIX",
    "TEMP_SUFFIX",
    "FolderLock",
    "acquire",
    "held_folder",
    "orphan_temporaries",
    "read_lock",
]

LOCK_NAME = ".pmsmjax.lock"
BREAK_NAME = ".pmsmjax.lock.break"
#: The temporary file of ``FOLDER/NAME`` being written is ``FOLDER/.NAME.XXXXXXXX.tmp`` (``mkstemp``'s eight
#: random characters between `TEMP_PREFIX` + NAME + ``.`` and `TEMP_SUFFIX`).
TEMP_PREFIX = "."
TEMP_SUFFIX = ".tmp"
_TEMP_NAME = re.compile(r"\..+\.[A-Za-z0-9_]{8}\.tmp")
#: How deep below the folder `orphan_temporaries` looks (a study's ``chunks/`` is one level down).
_TEMP_DEPTH = 2
#: A lock (or break file) whose JSON cannot be read is taken for one being written until it is this old, s.
UNREADABLE_STALE_S = 10.0


class FolderLock:
    """A held lock: `path` the lock file, `took_over` the stale lock's content it replaced (or None);
    `failed`: set by the holder when its command failed without raising (a nonzero exit status), so that
    [`held_folder`][pmsmjax.io.folder_lock.held_folder] tidies up as after an exception."""

    def __init__(self, path: Path, took_over: dict | None = None):
        self.path = path
        self.took_over = took_over
        self.failed = False

    def release(self) -> None:
        """Remove the lock file if it is still ours (idempotent)."""
        content = read_lock(self.path)
        if content is not None and content.get("pid") == os.getpid() and content.get("host") == _host():
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.path)


def _host() -> str:
    return socket.gethostname()


def read_lock(path: Path) -> dict | None:
    """The lock file's JSON content; None if it is absent or unreadable."""
    try:
        content = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    return content if isinstance(content, dict) else None


def _pid_runs(pid) -> bool:
    """Whether process `pid` runs on this host (a process of another user counts as running)."""
    if not isinstance(pid, int) or isinstance(pid, bool) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _is_stale(path: Path, content: dict | None) -> bool:
    if content is None:
        try:
            return time.time() - path.stat().st_mtime > UNREADABLE_STALE_S
        except FileNotFoundError:
            return True
    return content.get("host") == _host() and not _pid_runs(content.get("pid"))


def orphan_temporaries(folder) -> list[Path]:
    """The temporary files our writers leave in `folder` (and its sub-folders down to two levels, except a
    sub-folder with its own lock: another command's) when killed: names matching
    ``.NAME.XXXXXXXX.tmp`` only, so no file of the user's is ever taken for one."""
    folder = Path(folder)
    found = []
    for root, dirs, files in os.walk(folder):
        here = Path(root)
        depth = len(here.relative_to(folder).parts)
        if depth and LOCK_NAME in files:
            dirs.clear()
            continue
        if depth >= _TEMP_DEPTH:
            dirs.clear()
        found += [here / f for f in files if _TEMP_NAME.fullmatch(f) and (here / f).is_file()]
    return sorted(found)


def _remove_orphans(folder: Path) -> list[Path]:
    removed = []
    for p in orphan_temporaries(folder):
        with contextlib.suppress(OSError):
            p.unlink()
            removed.append(p)
    return removed


def _create(path: Path, content: dict) -> bool:
    """Create `path` holding `content`, atomically; False if it exists."""
    try:
        fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
    except FileExistsError:
        return False
    with os.fdopen(fd, "w") as f:
        json.dump(content, f)
    return True


def _describe(content: dict | None, path: Path) -> str:
    if content is None:
        return f"a command whose lock file {path} cannot be read"
    command = " ".join(str(a) for a in content.get("argv", [])) or "a pmsmjax command"
    return (
        f"'{command}' (pid {content.get('pid')} on host {content.get('host')}, started "
        f"{content.get('time', 'at an unknown time')})"
    )


def acquire(folder, argv: Sequence[str], attempts: int = 50) -> FolderLock:
    """Take the lock of the existing folder `folder` for the command line `argv` (what the message of a
    refused second command shows). Raises [`ParameterError`][pmsmjax.spec.validation.ParameterError] if
    another command holds it; takes a stale lock over with a warning (module docstring)."""
    path = Path(folder) / LOCK_NAME
    mine = {
        "pid": os.getpid(),
        "host": _host(),
        "argv": [str(a) for a in argv],
        "time": time.strftime("%Y-%m-%d %H:%M:%S %z"),
    }
    took_over = None
    for attempt in range(attempts):
        if _create(path, mine):
            if took_over is not None:
                removed = _remove_orphans(Path(folder))
                gone = (
                    f"; removed the {len(removed)} unfinished temporary file(s) it left"
                    f" ({', '.join(p.name for p in removed[:3])}{', ...' if len(removed) > 3 else ''})"
                    if removed
                    else ""
                )
                warnings.warn(
                    f"output folder {folder}: took over the lock of {_describe(took_over, path)}, which no "
                    f"longer runs (it ended without releasing the folder; its finished files are kept{gone})",
                    stacklevel=2,
                )
            return FolderLock(path, took_over)
        content = read_lock(path)
        if content is None and attempt < attempts - 1 and not _is_stale(path, None):
            time.sleep(0.02)  # created an instant ago, its content not yet written: read it again
            continue
        if not _is_stale(path, content):
            if content is None or content.get("host") == _host():
                fix = "wait for it to finish or write to another --out folder"
            else:
                fix = f"if it no longer runs on {content.get('host')}, delete {path}; else wait for it"
            raise ParameterError(
                f"output folder {folder} is in use by {_describe(content, path)}: {fix} (two commands "
                "writing one folder would mix their files)."
            )
        if _break_stale(path, content):
            took_over = content
        else:
            time.sleep(0.02)  # another command is taking the stale lock over: see whether it did
    raise ParameterError(  # pragma: no cover (needs a lock that keeps changing for a second)
        f"output folder {folder}: its lock {path} keeps changing: write to another --out folder."
    )


def _break_stale(path: Path, seen: dict | None) -> bool:
    """Remove the stale lock `path` whose content was `seen`, if no other command is doing so; True if
    this command removed it. The break file admits one remover; it re-reads the lock so that a fresh lock
    written meanwhile (by a command that took over first) is left alone."""
    breaker = path.with_name(BREAK_NAME)
    if not _create(breaker, {"pid": os.getpid(), "host": _host()}):
        if _is_stale(breaker, read_lock(breaker)):
            with contextlib.suppress(FileNotFoundError):
                os.unlink(breaker)  # a remover died in the few lines below
        return False
    try:
        if read_lock(path) != seen:
            return False
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)
        return True
    finally:
        os.unlink(breaker)


def _make_folders(folder: Path) -> list[Path]:
    """Create `folder` and its missing parents; the ones created, innermost first."""
    missing = [p for p in (folder, *folder.parents) if not p.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    return missing


@contextlib.contextmanager
def held_folder(folder, argv: Sequence[str]) -> Iterator[FolderLock]:
    """Hold the lock of `folder` (created if missing) while the block runs, for the command line `argv`.

    The lock goes when the block ends, however it ends (an exception, Ctrl-C). If the block raises or sets
    the lock's `failed`, the folders made here for the lock are removed again when they are empty, so that
    a refused command leaves nothing behind."""
    folder = Path(folder)
    created = _make_folders(folder)
    ok, lock = False, None
    try:
        lock = acquire(folder, argv)
        try:
            yield lock
            ok = True
        finally:
            lock.release()
    finally:
        if not ok or (lock is not None and lock.failed):
            for p in created:
                with contextlib.suppress(OSError):  # not empty: the command wrote something, keep it
                    p.rmdir()
