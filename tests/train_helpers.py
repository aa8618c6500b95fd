"""Shared pieces of the `train.py` end-to-end tests: a stand-in expert, private caches, a subprocess runner.

Every run is a subprocess on InvertedPendulum.balance.perfect with a tiny budget. The dataset comes from
a stand-in expert written here (a linear state-feedback controller stored as an `ExpertPolicy` file that
balances the pole for all 1000 steps) in a private `LOCO_IL_EXPERTS` folder, so the tests neither need
nor use the shipped expert, and are deterministic. Datasets are cached in a private `LOCO_IL_DATASETS`.
"""
from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]
TASK = "InvertedPendulum.balance.perfect"
GAINS = [1.0, 10.0, 1.0, 1.0]      # obs = [cart pos, pole angle, cart vel, pole ang. vel]; force range [-3, 3]
#: small, fast settings shared by every run: a 12-episode dataset pool (9 train / 3 held out), W&B off
FAST = ["dataset.n_episodes=12", "eval=quick", "logger=csv", "hydra/job_logging=disabled"]


def make_env_vars(root: Path) -> dict:
    """Environment of the subprocesses: the stand-in expert in `root`/experts, datasets cached in `root`/datasets."""
    from loco_il.experts.policy import ExpertPolicy
    expert = ExpertPolicy(4, 1, hidden=(), metadata={"task_id": TASK, "note": "linear stand-in expert (tests)"})
    with torch.no_grad():
        expert.policy.net[0].weight.copy_(torch.tensor([GAINS]) / 3.0)
        expert.policy.net[0].bias.zero_()
    (root / "experts" / "InvertedPendulum.balance").mkdir(parents=True)
    expert.save(root / "experts" / "InvertedPendulum.balance" / "expert.pt")
    env = dict(os.environ, LOCO_IL_EXPERTS=str(root / "experts"), LOCO_IL_DATASETS=str(root / "datasets"),
               WANDB_MODE="offline", WANDB_SILENT="true", MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"),
               OMP_NUM_THREADS="1", PYTHONUNBUFFERED="1", HYDRA_FULL_ERROR="1")
    env["_root"] = str(root)
    return env


def train_command(results: Path, *overrides: str, multirun: bool = False) -> list[str]:
    return [sys.executable, "train.py", *(["-m"] if multirun else []), f"results_dir={results}", *FAST, *overrides]


def train(env: dict, results: Path, *overrides: str, check: bool = True, timeout: int = 300,
          multirun: bool = False) -> subprocess.CompletedProcess:
    cmd = train_command(results, *overrides, multirun=multirun)
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout)
    if check and proc.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)} exited {proc.returncode}\nstdout:\n{proc.stdout[-3000:]}\n"
                             f"stderr:\n{proc.stderr[-3000:]}")
    return proc


def run_dir(results: Path, name: str = "bc", seed: int = 0) -> Path:
    return results / TASK / name / f"seed{seed}"


def csv_rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))
