"""Atomic writes (loco_il.utils.atomic): the target holds the old content or the whole new one, never a part."""
from __future__ import annotations

import pytest

from loco_il.utils.atomic import atomic_copy, atomic_write


def test_atomic_write_leaves_the_old_file_when_the_writer_fails(tmp_path):
    target = tmp_path / "data.bin"
    target.write_bytes(b"old")

    def half_then_fail(handle):
        handle.write(b"new, half")
        raise RuntimeError("killed mid-write")

    with pytest.raises(RuntimeError, match="mid-write"):
        atomic_write(target, half_then_fail)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["data.bin"]   # no temporary file left behind


def test_atomic_copy_copies_whole_files_and_keeps_the_target_on_a_missing_source(tmp_path):
    source, target = tmp_path / "src.pt", tmp_path / "kept" / "step5.pt"
    payload = bytes(range(256)) * 4096   # 1 MiB, more than one copy buffer
    source.write_bytes(payload)
    atomic_copy(source, target)
    assert target.read_bytes() == payload
    with pytest.raises(FileNotFoundError):
        atomic_copy(tmp_path / "missing.pt", target)
    assert target.read_bytes() == payload
