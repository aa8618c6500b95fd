"""The quadrupeds' built-in expert (the trot controller as an env-level policy): `perfect` datasets with
actions that replay exactly and walk at the command, `preference` levels ranked by return. Short
episodes (``horizon=``) keep these tests fast."""
from __future__ import annotations

import numpy as np
import pytest

from loco_il import LocoEnv
from loco_il.datasets import DatasetError
from loco_il.datasets.baselines import get_baseline
from loco_il.datasets.providers import expert as expert_mod
from loco_il.datasets.providers.expert import replay_episode
from loco_il.environments.registry import make
from loco_il.experts import files as expert_files
from loco_il.experts.trot import PREFERENCE_LEVELS, TrotExpert

GOAL_SPEED = 0.5
HORIZON = 250        # 2.5 s: speed ramp (0.5 s) plus two seconds of trot
SETTLE = 100         # steps left out of the speed measurement (start from standing)
VX = {"UnitreeA1": "dq_trunk_tx", "UnitreeGo1": "dq_root_vx"}


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path / "datasets"))
    monkeypatch.setenv("LOCO_IL_EXPERTS", str(tmp_path / "no-experts"))
    monkeypatch.setattr(expert_files, "SHIPPED_DIR", tmp_path / "no-shipped")   # the built-in expert, not a file


@pytest.mark.parametrize("body", ["UnitreeA1", "UnitreeGo1"])
def test_perfect_walks_and_replays_exactly(body):
    env = LocoEnv.make(f"{body}.simple.perfect")
    data, init = env.create_dataset(n_episodes=2, horizon=HORIZON, return_init_states=True, verbose=False)
    assert data.n_trajectories == 2 and len(init) == 2
    assert data.actions.shape == (data.n_transitions, env.model.nu) == (2 * HORIZON, 12)
    assert np.isfinite(data.actions).all() and np.abs(data.actions).max() <= 1.0
    assert not data.absorbing.any()                                    # no fall
    assert [b - a for a, b in data.episode_bounds()] == [HORIZON, HORIZON]
    info = data.info
    assert "not an RL policy" in info["expert"] and info["expert_metadata"]["task_id"] == f"{body}.simple"
    assert info["policy_checksum"] == TrotExpert(env).checksum()
    vx = data.obs[:, list(env.full_obs_spec.names).index(VX[body])]
    for a, b in data.episode_bounds():
        assert abs(vx[a + SETTLE:b].mean() - GOAL_SPEED) <= 0.2 * GOAL_SPEED   # the `real` provider's tolerance
    (a0, b0), (a1, b1) = data.episode_bounds()
    assert not np.allclose(data.actions[a0:b0], data.actions[a1:b1])   # per-episode gait variation
    replay_env = make(f"{body}.simple.perfect")
    for e, (a, b) in enumerate(data.episode_bounds()):
        out = replay_episode(replay_env, init.qpos[e], init.qvel[e], data.actions[a:b], seed=int(init.seeds[e]))
        np.testing.assert_allclose(out["obs"], data.obs[a:b], rtol=0, atol=1e-9)
        np.testing.assert_allclose(out["next_obs"], data.next_obs[a:b], rtol=0, atol=1e-9)
        np.testing.assert_allclose(out["rewards"], data.rewards[a:b], rtol=0, atol=1e-9)
        assert not out["absorbing"].any()


@pytest.mark.parametrize("body", ["UnitreeA1", "UnitreeGo1"])
def test_perfect_hard_walks_toward_each_episodes_direction(body):
    """`hard` draws a walking direction per episode; the controller turns and walks toward it (the directional
    velocity reward exp(-5 |v - v_cmd|) is 0.08 when standing still; over these first 2.5 s, which include the
    turn, the trot reaches 0.5-0.75 per step)."""
    env = LocoEnv.make(f"{body}.hard.perfect")
    data = env.create_dataset(n_episodes=2, horizon=HORIZON, verbose=False)
    assert not data.absorbing.any() and data.info["expert_metadata"]["task_id"] == f"{body}.hard"
    for a, b in data.episode_bounds():
        assert data.rewards[a + SETTLE:b].mean() > 0.4
    (a0, b0), (a1, b1) = data.episode_bounds()
    assert not np.allclose(data.obs[a0:b0], data.obs[a1:b1])


def test_perfect_is_deterministic_and_cached():
    env = LocoEnv.make("UnitreeA1.simple.perfect")
    stats = dict(expert_mod.STATS)
    first = env.create_dataset(n_episodes=1, horizon=50, verbose=False)
    assert expert_mod.STATS["generated"] == stats.get("generated", 0) + 1
    again = env.create_dataset(n_episodes=1, horizon=50, verbose=False)
    assert expert_mod.STATS["cache_hits"] == stats.get("cache_hits", 0) + 1
    fresh = env.create_dataset(n_episodes=1, horizon=50, verbose=False, regenerate=True)
    for d in (again, fresh):
        np.testing.assert_array_equal(d.actions, first.actions)
        np.testing.assert_array_equal(d.obs, first.obs)
    assert TrotExpert(env).checksum() == TrotExpert("UnitreeA1.simple").checksum()
    assert TrotExpert(env, action_noise=0.1).checksum() != TrotExpert(env).checksum()


def test_expert_needs_the_simulator_state():
    env = make("UnitreeA1.simple.perfect")
    pol = TrotExpert(env)
    with pytest.raises(RuntimeError, match="start_episode"):
        pol(env.reset())
    with pytest.raises(ValueError, match="not a quadruped"):
        TrotExpert("Hopper.run")


def test_replay_check_catches_a_policy_that_changes_the_simulation():
    class Meddler(TrotExpert):            # pushes the robot: its actions alone no longer explain the states
        def __call__(self, obs):
            self._env.data.qvel[0] += 0.01
            return super().__call__(obs)

    env = LocoEnv.make("UnitreeA1.simple.perfect")
    with pytest.raises(DatasetError, match="does not reproduce"):
        env.create_dataset(n_episodes=1, horizon=20, expert=Meddler(env), verbose=False)


def test_preference_levels_ranked_by_return():
    data = LocoEnv.make("UnitreeA1.simple.preference").create_dataset(n_episodes=1, horizon=300, verbose=False)
    levels = data.info["levels"]
    assert len(levels) == PREFERENCE_LEVELS >= 4 and data.info["n_levels"] == len(levels)
    means = [lvl["mean_return"] for lvl in levels]
    assert means == sorted(means) and means[-1] - means[0] > 50
    noise = [float(lvl["snapshot"].rsplit("std ", 1)[1].rstrip(")")) for lvl in levels]
    assert noise == sorted(noise, reverse=True)          # more action noise, lower return
    assert data.actions.shape == (data.n_transitions, 12)
    episode_returns = [data.rewards[a:b].sum() for a, b in data.episode_bounds()]
    np.testing.assert_allclose(episode_returns, means)   # one episode per level, worst first


def test_baselines_record_the_trot_controller():
    for task in ("UnitreeA1.simple", "UnitreeGo1.simple", "UnitreeA1.hard", "UnitreeGo1.hard"):
        base = get_baseline(task)
        assert "not an RL policy" in base["expert"]["source"] and base["expert"]["expert_file"] is None
        assert base["expert"]["return_mean"] > 700 > 100 > base["random"]["return_mean"]
