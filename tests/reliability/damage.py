"""Ways to damage a file the way a disk or a careless copy does (size unchanged, or cut short)."""
from __future__ import annotations

import struct
import zipfile
from pathlib import Path


def flip_tensor_bytes(path: Path, n: int = 64) -> None:
    """XOR `n` bytes in the middle of the largest tensor stored in a torch file (a zip of raw storages)."""
    with zipfile.ZipFile(path) as zf:
        info = max((i for i in zf.infolist() if "/data/" in i.filename), key=lambda i: i.file_size)
    assert info.file_size >= n and info.compress_type == zipfile.ZIP_STORED
    with open(path, "r+b") as fh:
        fh.seek(info.header_offset + 26)
        name_len, extra_len = struct.unpack("<HH", fh.read(4))
        start = info.header_offset + 30 + name_len + extra_len + (info.file_size - n) // 2
        fh.seek(start)
        data = bytes(b ^ 0xFF for b in fh.read(n))
        fh.seek(start)
        fh.write(data)


def truncate(path: Path, keep: float = 0.5) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])
