"""The mission's command, `python train.py task=Atlas.walk.perfect algo=lsiq`, from the shipped Atlas.walk expert:
the `perfect` dataset is generated from it (2 episodes, in a private cache) and LS-IQ trains on it end to end
(a tiny budget: a smoke test of the pipeline, not of learning)."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest

from train_helpers import ROOT, train  # tests/ is on sys.path

pytestmark = pytest.mark.slow      # a subprocess run of train.py: the full suite (CI) runs them; -m "not slow" skips them

TASK = "Atlas.walk.perfect"


def test_lsiq_trains_on_atlas_walk_perfect_from_the_shipped_expert(tmp_path):
    env = dict(os.environ, LOCO_IL_DATASETS=str(tmp_path / "datasets"), LOCO_IL_EXPERTS="", WANDB_MODE="offline",
               WANDB_SILENT="true", OMP_NUM_THREADS="1", PYTHONUNBUFFERED="1", HYDRA_FULL_ERROR="1")
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    results = tmp_path / "results"
    train(env, results, f"task={TASK}", "algo=lsiq", "dataset.n_episodes=2", "n_steps=300",
          "algo.policy.hidden=[32,32]", "algo.params.critic_hidden=[32,32]", "algo.params.initial_replay_size=100",
          "algo.params.batch_size=64", "algo.params.expert_batch_size=64", "eval.every=300",
          "eval.final_episodes=2", "eval.similarity=false", timeout=600)
    result = json.loads((results / TASK / "lsiq" / "seed0" / "eval.json").read_text())
    assert (result["task_id"], result["algorithm"], result["dataset_type"]) == (TASK, "lsiq", "perfect")
    assert result["env_steps"] == 300 and result["episodes"] == 2
    # the dataset is the shipped expert's rollouts: 2 episodes walking to the horizon, with actions
    (path,) = [p for p in (tmp_path / "datasets" / "Atlas.walk").glob("perfect-n2-seed0-*.npz")
               if not p.name.endswith(".init_states.npz")]
    with np.load(path, allow_pickle=False) as data:
        info = json.loads(str(data["info_json"]))
        assert data["actions"].shape == (2000, 10) and not data["absorbing"].any()
        assert data["rewards"].sum() / 2 > 900
    assert info["expert"].endswith("shipped/Atlas.walk/expert.pt") and info["expert_metadata"]["training_steps"] > 0
    # normalized against the recorded Atlas.walk baselines (random and the shipped expert)
    assert result["baseline"]["expert"] > 900 and result["normalized_score"] is not None
