"""The LocoMuJoCo model cache is filled once even when several processes start on an empty cache."""
from __future__ import annotations

import multiprocessing as mp
import time
from pathlib import Path

from loco_il.environments import assets


def _slow_fetch(root: Path) -> None:
    # stands in for download + extraction: slow enough that the processes overlap
    with open(root.parent / "fetches.log", "a") as fh:
        fh.write("fetch\n")
    time.sleep(0.5)
    root.mkdir(parents=True)
    (root / "atlas.xml").write_text("<mujoco/>")
    (root / ".complete").write_text("ok")


def _load(cache: str, out: "mp.Queue") -> None:
    import os
    os.environ["LOCO_IL_ASSETS"] = cache
    assets._fetch_locomujoco = _slow_fetch
    root = assets.locomujoco_root()
    out.put((root / "atlas.xml").read_text())


def test_parallel_first_use_fetches_once(tmp_path):
    ctx = mp.get_context("fork")
    out = ctx.Queue()
    procs = [ctx.Process(target=_load, args=(str(tmp_path), out)) for _ in range(3)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(30)
    assert [p.exitcode for p in procs] == [0, 0, 0]
    assert sorted(out.get(timeout=5) for _ in procs) == ["<mujoco/>"] * 3
    assert (tmp_path / "fetches.log").read_text().count("fetch") == 1
