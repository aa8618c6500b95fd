"""One training process per run dir: an OS lock (`fcntl.flock`) on `<run_dir>/.lock`.

Two processes training the same run dir would interleave their log rows and overwrite each other's
checkpoints. The lock is held for as long as the process trains; the OS releases it when the process
ends in any way (also SIGKILL), so a killed run never leaves a stale lock behind. The file itself stays
and names the last holder (pid, host, start time), which is what a refused second process reports.
"""
from __future__ import annotations

import contextlib
import datetime
import fcntl
import os
import socket
from pathlib import Path
from typing import Iterator

LOCK_NAME = ".lock"


class RunDirLockedError(RuntimeError):
    """Another process holds the run dir's lock."""


def _holder(path: Path) -> str:
    try:
        text = path.read_text().strip()
    except OSError:
        text = ""
    return text or "another process (holder unknown)"


@contextlib.contextmanager
def run_dir_lock(run_dir: str | os.PathLike) -> Iterator[Path]:
    """Hold the run dir's lock for the block; raise `RunDirLockedError` at once if another process holds it."""
    path = Path(run_dir) / LOCK_NAME
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise RunDirLockedError(
                f"{run_dir} is in use by {_holder(path)}; wait for that run to end (or stop it), or train "
                f"into another dir (name=<label>, seed=<n> or results_dir=<dir>)") from None
        started = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()} on host {socket.gethostname()} (since {started})\n".encode(), 0)
        yield path
    finally:
        os.close(fd)   # releases the lock (the OS does the same when the process dies)


__all__ = ["LOCK_NAME", "RunDirLockedError", "run_dir_lock"]
