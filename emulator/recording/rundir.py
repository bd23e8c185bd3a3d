"""Run directories as a resource: one run at a time, never over a finished run, no symlinks followed.

:func:`claim_run_dir` is held for the whole of a run (by :func:`emulator.assembly.session.run_emulator`;
the recorder writes through :func:`open_no_follow`):

* a path that exists and is not a directory (``--out file.txt``) is refused;
* a directory that another process is running in is refused, naming the process that holds it
  (an advisory ``flock`` on ``.psns-hil.lock`` inside the directory, which also carries that pid);
* a directory that already holds a run (``summary.json``, ``nav.csv``, ``capture.psnscap``, ...) is refused
  unless ``force``; with ``force`` it is emptied first (links are removed, never followed);
* any other non-empty directory is refused (it is not a run directory, so even ``force`` does not empty it);
* when the run ends with an error before it started (bad input: a missing device, a bad port), a directory
  that the claim created is removed again, so a bad-input exit leaves nothing behind.

Refusals raise :class:`RunDirError` (a :class:`~emulator.errors.EmulatorError`: exit 2 on the command line).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from ..errors import EmulatorError

__all__ = ["LOCK_NAME", "RUN_FILES", "RunDirError", "claim_run_dir", "open_no_follow"]

LOCK_NAME = ".psns-hil.lock"
#: files that mark a directory as a run directory
RUN_FILES = ("summary.json", "nav.csv", "truth.csv", "events.jsonl", "capture.psnscap", "ports.json",
             "timeline.csv", "report.html", LOCK_NAME)


class RunDirError(EmulatorError):
    """The run directory cannot be used (busy, finished, a file, not a run directory)."""


def _holder(lock_path: Path) -> str:
    try:
        pid = lock_path.read_text(encoding="utf-8").strip()
    except OSError:
        pid = ""
    return f"pid {pid}" if pid.isdigit() else "another process"


def open_no_follow(path: Path, mode: str = "w", newline: str | None = None) -> IO[Any]:
    """Open ``path`` for writing (``w`` text, ``wb`` bytes), truncating it, but refuse to follow a symlink
    there (``O_NOFOLLOW``)."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(path, flags, 0o644)
    except OSError as exc:
        raise RunDirError(f"{path}: cannot write ({exc.strerror}); the run never follows a link in its "
                          "directory") from exc
    if "b" in mode:
        return open(fd, mode)
    return open(fd, mode, encoding="utf-8", newline=newline)


def preflight_run_dir(run_dir: Path, force: bool = False) -> None:
    """The checks of :func:`claim_run_dir` that need no lock and change nothing (a file, a dangling link, a
    directory that holds something else or a run without ``force``): the CLI calls it before it announces a run,
    so a refused ``--out`` is the only line the user sees."""
    run_dir = Path(run_dir)
    if run_dir.is_symlink() and not run_dir.is_dir():
        raise RunDirError(f"{run_dir}: a dangling link, not a directory")
    if run_dir.exists() and not run_dir.is_dir():
        raise RunDirError(f"{run_dir}: exists and is not a directory (--out takes a run directory)")
    if run_dir.is_dir():
        entries = {e.name for e in run_dir.iterdir() if e.name != LOCK_NAME}
        if entries and not entries & set(RUN_FILES):
            raise RunDirError(f"{run_dir}: not empty and not a run directory; psns-hil writes only into a new "
                              "or empty directory, or replaces a finished run with --force")
        if entries and not force:
            raise RunDirError(f"{run_dir}: already holds a run ({', '.join(sorted(entries & set(RUN_FILES)))}); "
                              "pass --force to replace it (its contents are removed first) or choose another --out")


@contextlib.contextmanager
def claim_run_dir(run_dir: Path, force: bool = False) -> Iterator[Path]:
    """Hold ``run_dir`` for one run (see module docstring)."""
    run_dir = Path(run_dir)
    if run_dir.is_symlink() and not run_dir.is_dir():
        raise RunDirError(f"{run_dir}: a dangling link, not a directory")
    if run_dir.exists() and not run_dir.is_dir():
        raise RunDirError(f"{run_dir}: exists and is not a directory (--out takes a run directory)")
    created = not run_dir.exists()
    run_dir.mkdir(parents=True, exist_ok=True)
    lock_path = run_dir / LOCK_NAME
    lock_created = not lock_path.exists()
    try:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
    except OSError as exc:
        raise RunDirError(f"{run_dir}: cannot lock the run directory ({exc.strerror})") from exc
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise RunDirError(f"{run_dir}: in use by a running psns-hil ({_holder(lock_path)}); choose another "
                              "--out or wait for it to finish") from None
        try:
            _check_contents(run_dir, force)
        except RunDirError:
            if created:
                shutil.rmtree(run_dir, ignore_errors=True)
            elif lock_created:
                lock_path.unlink(missing_ok=True)
            raise
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        try:
            yield run_dir
        except BaseException as exc:
            recorded = any((run_dir / name).exists() for name in ("summary.json", "capture.psnscap"))
            if created and not recorded and not isinstance(exc, KeyboardInterrupt):
                # a bad-input exit (the run never started): leave nothing behind
                shutil.rmtree(run_dir, ignore_errors=True)
            else:  # what an interrupted or failed run recorded is kept
                lock_path.unlink(missing_ok=True)
            raise
        else:
            lock_path.unlink(missing_ok=True)
    finally:
        os.close(fd)


def _check_contents(run_dir: Path, force: bool) -> None:
    entries = [e for e in run_dir.iterdir() if e.name != LOCK_NAME]
    if not entries:
        return
    names = {e.name for e in entries}
    if not names & set(RUN_FILES):
        raise RunDirError(f"{run_dir}: not empty and not a run directory; psns-hil writes only into a new "
                          "or empty directory, or replaces a finished run with --force")
    if not force:
        raise RunDirError(f"{run_dir}: already holds a run ({', '.join(sorted(names & set(RUN_FILES)))}); "
                          "pass --force to replace it (its contents are removed first) or choose another --out")
    _clean_except_lock(run_dir)


def _clean_except_lock(run_dir: Path) -> None:
    for entry in run_dir.iterdir():
        if entry.name == LOCK_NAME:
            continue
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry)
        else:
            entry.unlink()
