"""`init_state=dataset`: training episodes start from states of the expert train split (LocoMuJoCo's choice)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from loco_il.datasets import Trajectories
from loco_il.environments.registry import make
from loco_il.experiment.checkpoint import config_differences
from loco_il.experiment.runner import ExperimentConfigError, training_start_sampler
from tests.experiment.test_train import TASK, env_vars, run_dir, train  # noqa: F401 (env_vars: fixture)


def rollout_dataset(env, episodes: int = 2, steps: int = 15, seed: int = 0) -> Trajectories:
    """Short random-action episodes of `env` (full observations), recorded like a dataset."""
    rng = np.random.default_rng(seed)
    parts = {k: [] for k in ("obs", "next_obs", "actions", "rewards", "absorbing", "last")}
    for ep in range(episodes):
        env.seed(100 + ep)
        obs = env.reset()
        for t in range(steps):
            action = rng.uniform(-1, 1, env.info.action_space.shape)
            nxt, reward, absorbing, _ = env.step(action)
            for key, value in zip(parts, (obs, nxt, action, reward, absorbing, absorbing or t == steps - 1)):
                parts[key].append(value)
            obs = nxt
            if absorbing:
                break
    arrays = {k: np.asarray(v) for k, v in parts.items()}
    return Trajectories(**arrays, info={"task_id": env.task_id, "dataset_type": "perfect", "source": "test"})


def test_dataset_start_states_are_states_of_the_train_split():
    env = make(TASK, seed=0)
    data = rollout_dataset(make(TASK, seed=1), episodes=8)
    states = np.concatenate([data.obs, data.next_obs[data.last]])
    env.init_state_sampler = training_start_sampler(env, "dataset", {}, data)
    starts = np.array([env.reset() for _ in range(300)])
    dist = np.abs(starts[:, None, :] - states[None, :, :]).max(axis=2)   # (starts, dataset states)
    assert dist.min(axis=1).max() < 1e-9                                 # every start is a dataset state
    assert len(np.unique(dist.argmin(axis=1))) > 0.8 * len(states)       # drawn across the dataset
    env.init_state_sampler = training_start_sampler(env, "default", {}, data)
    assert env.init_state_sampler is None
    assert np.abs(env.reset()).max() < 0.02                              # the body's own start (noise 0.01)


def test_pomdp_task_rebuilds_start_states_from_full_observations(tmp_path, monkeypatch):
    """A `.pomdp` train split hides the velocities; the start states come from its full-observation twin."""
    from loco_il.datasets import create_dataset
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path))
    env = make(TASK + ".pomdp", seed=0)
    dcfg = {"n_episodes": 4}
    masked = create_dataset(env, split="train", n_episodes=4, verbose=False)
    assert masked.obs_dim < env.full_obs_spec.dim
    env.init_state_sampler = training_start_sampler(env, "dataset", dcfg, masked)
    full = create_dataset(env, split="train", n_episodes=4, full_obs=True, verbose=False)
    env.reset()
    state = np.concatenate([env.data.qpos, env.data.qvel])
    assert np.abs(np.concatenate([full.obs, full.next_obs]) - state).max(axis=1).min() < 1e-9


def test_unknown_init_state_is_refused():
    env = make(TASK, seed=0)
    with pytest.raises(ExperimentConfigError, match="expected one of default, dataset"):
        training_start_sampler(env, "keyframe", {}, None)


def test_runs_checkpointed_before_init_state_existed_still_resume():
    old = {"task_id": TASK, "algo": {"name": "sqil"}, "seed": 0}
    assert config_differences(old, {**old, "init_state": "default"}) == []
    assert config_differences(old, {**old, "init_state": "dataset"}) == ["init_state: 'default' -> 'dataset'"]


@pytest.mark.slow
def test_train_py_with_dataset_start_states(env_vars, tmp_path):
    results = tmp_path / "results"
    proc = train(env_vars, results, "algo=sqil", "init_state=dataset", "n_steps=600", "eval.every=300",
                 "algo.params.initial_replay_size=200", "algo.params.batch_size=64",
                 "algo.params.expert_batch_size=64", "algo.policy.hidden=[32,32]", "algo.params.critic_hidden=[32,32]")
    assert "training episodes start from states of the expert train split" in proc.stdout
    assert json.loads((run_dir(results, "sqil") / "eval.json").read_text())["env_steps"] == 600
    bad = train(env_vars, tmp_path / "bad", "algo=sqil", "init_state=keyframe", check=False, timeout=120)
    assert bad.returncode == 2 and "init_state='keyframe': expected one of default, dataset" in bad.stderr
