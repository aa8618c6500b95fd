"""Only each run's small files can be committed from benchmarks/leaderboard/logs/: checkpoints (with the replay
memory), agents, Hydra's and W&B's folders stay out of git."""
from __future__ import annotations

import shutil
import subprocess

import pytest

from loco_il.benchmark import paths

RUN = "small/Hopper.run.perfect/lsiq/seed0"
KEPT = ["eval.json", "log.csv", "log.jsonl", "config.yaml"]
IGNORED = ["checkpoint.pt", "checkpoint.prev.pt", "checkpoint.json", "final_agent.pt", "final_agent.pt.sha256",
           ".lock", "train.log", ".hydra/config.yaml", "wandb/offline-run-1/run.wandb",
           "kept/step100.pt"]


@pytest.mark.skipif(shutil.which("git") is None or not (paths.ROOT / ".git").exists(),
                    reason="needs git and a git checkout")
def test_only_small_files_are_committed():
    def ignored(rel: str) -> bool:
        path = paths.LOGS_DIR / rel
        code = subprocess.run(["git", "check-ignore", "-q", "--no-index", str(path)], cwd=paths.ROOT).returncode
        assert code in (0, 1), f"git check-ignore failed on {path}"
        return code == 0
    assert [f for f in KEPT if ignored(f"{RUN}/{f}")] == []
    assert [f for f in IGNORED if not ignored(f"{RUN}/{f}")] == []
    assert ignored("small/multirun.yaml") and ignored("small/.submitit/1/log.out")
    assert not ignored(".gitignore")
