"""Run directories as a resource: one run at a time, never over a finished run, no symlinks followed.

:func:`claim_run_dir` is held for the whole of a run (by :func:`emulator.assembly.session.run_emulator`;
the recorder writes through :func:`open_no_follow`):

* a path that exists and is not a directory (``--out file.txt``) is refused;
* a directory that another process is running in is refused, naming the process that holds it
  (an advisory ``flock`` on ``.psns-hil.lock`` inside the directory, which also carries that pid);
* a directory that already holds a run is refused unless ``force``; with ``force`` it is emptied first (links
  are removed, never followed). *Holds a run* means proven (:func:`is_run_dir`): the run's lock file
  ``.psns-hil.lock`` (left by a run that was killed or stopped at once) or a ``summary.json`` that validates
  against the summary model; a file name such as ``report.html`` alone proves nothing (issue 41: a directory with
  ``thesis.tex``, ``sub/`` and one ``report.html`` was emptied);
* ``force`` never acts through a symbolic link: ``--out`` that is a link, or a ``summary.json`` / lock that is a
  link, is refused;
* any other non-empty directory is refused (it is not a run directory, so even ``force`` does not empty it);
* the directory cannot be created or written (a read-only mount, no permission): refused with the reason;
* when the run ends with an error before it started (bad input: a missing device, a bad port), a directory
  that the claim created is removed again, so a bad-input exit leaves nothing behind.

Refusals raise :class:`RunDirError` (a :class:`~emulator.errors.EmulatorError`: exit 2 on the command line).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from ..errors import EmulatorError, PsnsHilError

__all__ = ["LOCK_NAME", "RUN_FILES", "SUMMARY_RESERVE_NAME", "RunDirError", "claim_run_dir", "is_run_dir",
           "open_no_follow", "preflight_run_dir"]

LOCK_NAME = ".psns-hil.lock"
#: space held for summary.json while the run writes (emulator.recording.recorder.Recorder: a full disk still
#: gets its summary)
SUMMARY_RESERVE_NAME = ".psns-hil.summary-reserve"
#: files a run writes (named in the refusal of a finished run; not proof of a run: :func:`is_run_dir`)
RUN_FILES = ("summary.json", "nav.csv", "truth.csv", "events.jsonl", "capture.psnscap", "ports.json",
             "clock.json", "timeline.csv", "report.html", LOCK_NAME)


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


#: a summary.json larger than this is not read to prove a run directory (a real one is a few hundred KB)
SUMMARY_PROOF_MAX_BYTES = 16 * 1024 * 1024


def is_run_dir(run_dir: Path, lock_counts: bool = True) -> bool:
    """True when ``run_dir`` provably holds a psns-hil run: its lock file ``.psns-hil.lock`` (a regular file, not a
    link), or a ``summary.json`` (a regular file, not a link, at most :data:`SUMMARY_PROOF_MAX_BYTES`) that validates
    against :class:`~emulator.recording.summary_model.RunSummary`. ``lock_counts=False``: the lock file was just
    created by this process's claim, so it proves nothing."""
    lock = run_dir / LOCK_NAME
    if lock_counts and lock.is_file() and not lock.is_symlink():
        return True
    summ = run_dir / "summary.json"
    try:
        st = summ.lstat()
    except OSError:
        return False
    if not stat.S_ISREG(st.st_mode) or st.st_size > SUMMARY_PROOF_MAX_BYTES:
        return False
    from .summary_model import load_summary  # pydantic: only when a directory has to be proven

    try:
        load_summary(summ)
    except PsnsHilError:
        return False
    return True


def _check_path(run_dir: Path, force: bool) -> None:
    if run_dir.is_symlink() and not run_dir.is_dir():
        raise RunDirError(f"{run_dir}: a dangling link, not a directory")
    if run_dir.exists() and not run_dir.is_dir():
        raise RunDirError(f"{run_dir}: exists and is not a directory (--out takes a run directory)")
    if force and run_dir.is_symlink():
        raise RunDirError(f"{run_dir}: a symbolic link; --force never empties a directory through a link (give the "
                          "directory itself)")


def _refuse_contents(run_dir: Path, force: bool, lock_counts: bool = True) -> bool:
    """Raise :class:`RunDirError` unless ``run_dir`` may be used; True when it must be emptied first."""
    entries = {e.name for e in run_dir.iterdir() if e.name != LOCK_NAME}
    if not entries:
        return False
    if not is_run_dir(run_dir, lock_counts):
        raise RunDirError(f"{run_dir}: not empty and not a run directory (no {LOCK_NAME} and no valid summary.json); "
                          "psns-hil writes only into a new or empty directory, or replaces a finished run with --force")
    if not force:
        raise RunDirError(f"{run_dir}: already holds a run ({', '.join(sorted(entries & set(RUN_FILES))) or 'files'});"
                          " pass --force to replace it (its contents are removed first) or choose another --out")
    return True


def preflight_run_dir(run_dir: Path, force: bool = False) -> None:
    """The checks of :func:`claim_run_dir` that need no lock and change nothing (a file, a dangling link, a
    directory that holds something else or a run without ``force``): the CLI calls it before it announces a run,
    so a refused ``--out`` is the only line the user sees."""
    run_dir = Path(run_dir)
    _check_path(run_dir, force)
    if run_dir.is_dir():
        _refuse_contents(run_dir, force)
    near = run_dir.absolute()
    while not near.exists() and near.parent != near:
        near = near.parent
    if not os.access(near, os.W_OK | os.X_OK):  # a read-only mount (EROFS even for root) or no permission
        what = "cannot write the run directory" if near == run_dir.absolute() else f"cannot create it in {near}"
        raise RunDirError(f"{run_dir}: {what} (read-only file system or no permission)")


@contextlib.contextmanager
def claim_run_dir(run_dir: Path, force: bool = False) -> Iterator[Path]:
    """Hold ``run_dir`` for one run (see module docstring)."""
    run_dir = Path(run_dir)
    _check_path(run_dir, force)
    created = not run_dir.exists()
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RunDirError(f"{run_dir}: cannot create the run directory ({exc.strerror})") from None
    lock_path = run_dir / LOCK_NAME
    lock_created = not lock_path.exists()
    try:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
    except OSError as exc:
        raise RunDirError(f"{run_dir}: cannot write the run directory ({exc.strerror})") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise RunDirError(f"{run_dir}: in use by a running psns-hil ({_holder(lock_path)}); choose another "
                              "--out or wait for it to finish") from None
        try:
            _check_contents(run_dir, force, lock_counts=not lock_created)
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
            # what an interrupted or failed run recorded is kept, with its lock file unless a summary was written:
            # the proof (is_run_dir) that --force may replace it
            elif (run_dir / "summary.json").exists():
                lock_path.unlink(missing_ok=True)
            raise
        else:
            lock_path.unlink(missing_ok=True)
    finally:
        os.close(fd)


def _check_contents(run_dir: Path, force: bool, lock_counts: bool) -> None:
    if _refuse_contents(run_dir, force, lock_counts):
        _clean_except_lock(run_dir)


def _clean_except_lock(run_dir: Path) -> None:
    for entry in run_dir.iterdir():
        if entry.name == LOCK_NAME:
            continue
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry)
        else:
            entry.unlink()
