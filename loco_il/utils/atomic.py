"""Atomic file writes: a crash mid-write never leaves a half-written checkpoint or dataset.

Write to a temporary file in the target's directory, flush it to disk, then `os.replace`
it over the target (atomic on POSIX and Windows when both are on one filesystem).
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import IO, Callable, Iterator

import torch


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "wb") -> Iterator[IO]:
    """Open a temporary file that replaces `path` only if the block finishes without error."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.chmod(tmp, 0o666 & ~_umask())   # mkstemp makes 0600 files; give the usual permissions
    try:
        with os.fdopen(fd, mode) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: str | os.PathLike, writer: Callable[[IO], None]) -> None:
    """Call `writer(file_handle)` on a temporary file, then move it onto `path`."""
    with atomic_open(path) as handle:
        writer(handle)


def atomic_copy(source: str | os.PathLike, path: str | os.PathLike) -> None:
    """Copy `source` to `path`; `path` holds either its old content or the whole copy, never a part."""
    import shutil
    with open(source, "rb") as src:
        atomic_write(path, lambda handle: shutil.copyfileobj(src, handle))


def atomic_torch_save(obj: object, path: str | os.PathLike) -> None:
    """`torch.save` that never leaves a truncated file behind."""
    atomic_write(path, lambda handle: torch.save(obj, handle))
