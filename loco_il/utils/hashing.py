"""Checksums used for cache keys and archive verification."""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any


def file_sha256(path: str | os.PathLike) -> str:
    """sha256 hex digest of a file, read in 1 MiB blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def plain_json(obj: Any) -> Any:
    """``obj`` as plain JSON types (arrays as lists, anything else unknown as its ``str``): the stable form of
    parameters that go into a hashed cache key."""
    return json.loads(json.dumps(obj, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))


#: suffix of a checksum file next to the file it covers (`sha256sum -c` reads it)
SIDECAR_SUFFIX = ".sha256"


class ChecksumMismatchError(ValueError):
    """A file's bytes do not hash to the sha256 recorded for it (damaged or replaced)."""


def sidecar_path(path: str | os.PathLike) -> Path:
    path = Path(path)
    return path.with_name(path.name + SIDECAR_SUFFIX)


def write_sidecar(path: str | os.PathLike) -> str:
    """Record `path`'s sha256 in `<path>.sha256` (sha256sum's format), atomically; returns the digest."""
    from loco_il.utils.atomic import atomic_open
    path = Path(path)
    digest = file_sha256(path)
    with atomic_open(sidecar_path(path), "w") as fh:
        fh.write(f"{digest}  {path.name}\n")
    return digest


def verify_sidecar(path: str | os.PathLike) -> bool:
    """Check `path` against `<path>.sha256`: True when it matches, False when no checksum was recorded (files
    written before checksums existed); raise `ChecksumMismatchError` naming the file when it differs."""
    path = Path(path)
    try:
        recorded = sidecar_path(path).read_text().split()[0]
    except (OSError, IndexError):
        return False
    actual = file_sha256(path)
    if actual != recorded:
        raise ChecksumMismatchError(f"{path} is damaged: its sha256 {actual[:12]}... differs from the "
                                    f"{recorded[:12]}... recorded in {sidecar_path(path).name}")
    return True
