"""The one episode loop (`loco_il.environments.episodes`): where an episode stops, when the start hook runs,
what is recorded, how actions are checked and clipped, and that a recorded episode replays exactly."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from loco_il.environments.episodes import (Outcome, UniformRandomPolicy, episode_seeds, outcome_arrays,
                                           replay_episode, run_episode, run_episodes)
from loco_il.environments.registry import make


class CountingEnv:
    """Observation [t], reward t at step t, absorbing at step ``fall_at`` (never if None); logs every call."""

    def __init__(self, fall_at: int | None = None, nu: int = 2):
        self.fall_at, self.calls, self.t = fall_at, [], 0
        self.model = SimpleNamespace(nu=nu)

    def seed(self, seed):
        self.calls.append(("seed", seed))

    def reset(self):
        self.t = 0
        self.calls.append(("reset",))
        return np.array([0.0])

    def step(self, action):
        self.calls.append(("step", np.array(action)))
        self.t += 1
        return np.array([float(self.t)]), float(self.t), self.t == self.fall_at, {}


class HookedPolicy:
    """Zero actions; logs its start hook into the env's call log."""

    def __init__(self, nu: int = 2):
        self.nu = nu

    def start_episode(self, env, seed):
        env.calls.append(("start_episode", seed))

    def __call__(self, obs):
        return np.zeros(self.nu)


def test_stops_after_the_absorbing_step():
    env = CountingEnv(fall_at=3)
    ep = run_episode(env, HookedPolicy(), seed=5, horizon=10)
    assert ep.length == 3 and ep.terminated
    assert ep.absorbing.tolist() == [False, False, True]
    assert ep.rewards.tolist() == [1.0, 2.0, 3.0] and ep.ret == 6.0
    assert ep.outcome == Outcome(6.0, 3, True)


def test_stops_at_the_horizon_without_terminating():
    env = CountingEnv(fall_at=None)
    ep = run_episode(env, HookedPolicy(), seed=5, horizon=4)
    assert ep.length == 4 and not ep.terminated and not ep.absorbing.any()
    assert sum(call[0] == "step" for call in env.calls) == 4


def test_start_hook_runs_after_the_reset_with_the_seed():
    env = CountingEnv(fall_at=2)
    run_episode(env, HookedPolicy(), seed=42, horizon=10)
    assert [c[0] for c in env.calls[:4]] == ["seed", "reset", "start_episode", "step"]
    assert env.calls[0] == ("seed", 42) and env.calls[2] == ("start_episode", 42)


def test_on_state_sees_the_start_and_every_step():
    env = CountingEnv(fall_at=None)
    seen = []
    run_episode(env, HookedPolicy(), seed=0, horizon=3, on_state=lambda e: seen.append(e.t))
    assert seen == [0, 1, 2, 3]


def test_clip_clips_before_stepping_and_refuses_bad_actions():
    env = CountingEnv(fall_at=None)
    run_episode(env, lambda obs: np.array([5.0, -0.5]), seed=0, horizon=2, clip=True)
    assert [c[1].tolist() for c in env.calls if c[0] == "step"] == [[1.0, -0.5], [1.0, -0.5]]
    with pytest.raises(ValueError, match="non-finite action at step 0"):
        run_episode(CountingEnv(), lambda obs: np.array([np.nan, 0.0]), seed=0, horizon=2, clip=True)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        run_episode(CountingEnv(), lambda obs: np.zeros(3), seed=0, horizon=2, clip=True)
    raw = CountingEnv()
    run_episode(raw, lambda obs: np.array([5.0, 0.0]), seed=0, horizon=1)   # without clip: as the policy says
    assert raw.calls[-1][1].tolist() == [5.0, 0.0]


def test_run_episodes_follows_the_seeds_in_order():
    env = CountingEnv(fall_at=2)
    order = []
    eps = run_episodes(env, HookedPolicy(), [7, 8, 9], horizon=10, on_episode=lambda i, ep: order.append((i, ep.seed)))
    assert order == [(0, 7), (1, 8), (2, 9)] and [ep.seed for ep in eps] == [7, 8, 9]
    assert [c[1] for c in env.calls if c[0] == "seed"] == [7, 8, 9]


def test_episode_seeds_are_prefix_stable_and_distinct():
    five = episode_seeds(0, 5)
    assert np.array_equal(episode_seeds(0, 3), five[:3]) and len(set(five.tolist())) == 5
    assert not np.array_equal(episode_seeds(1, 3), five[:3])


def test_outcome_arrays_types():
    returns, lengths, terminated = outcome_arrays([Outcome(1.5, 3, True), Outcome(2.0, 10, False)])
    assert returns.dtype == np.float64 and lengths.dtype == np.int64 and terminated.dtype == bool
    assert returns.tolist() == [1.5, 2.0] and lengths.tolist() == [3, 10] and terminated.tolist() == [True, False]


def test_uniform_random_policy_continues_its_stream():
    policy = UniformRandomPolicy((3,), np.random.default_rng(0))
    draws = np.array([policy(None) for _ in range(4)])
    assert np.array_equal(draws, np.random.default_rng(0).uniform(-1.0, 1.0, (4, 3)))
    assert draws.min() >= -1.0 and draws.max() < 1.0


def test_recorded_episode_shapes_and_exact_replay():
    env = make("Hopper.run.perfect")
    try:
        policy = UniformRandomPolicy(int(env.model.nu), np.random.default_rng(3))
        ep = run_episode(env, lambda obs: 2.0 * policy(obs), seed=11, horizon=40, record=True, clip=True)
        n, dim, nu = ep.length, env.obs_spec.dim, int(env.model.nu)
        assert 0 < n <= 40
        assert ep.obs.shape == ep.next_obs.shape == (n, dim) and ep.actions.shape == (n, nu)
        assert np.array_equal(ep.obs[1:], ep.next_obs[:-1]) and np.array_equal(ep.obs[0], ep.start_obs)
        assert np.abs(ep.actions).max() <= 1.0 and np.abs(ep.actions).max() == 1.0    # clipped, and clipping bit
        assert ep.qpos.shape == (env.model.nq,) and ep.qvel.shape == (env.model.nv,)
        assert ep.xy_start.shape == ep.xy_end.shape == (2,)
        assert np.isfinite(ep.forward_speed(env.dt))
        assert np.isclose(ep.ret, np.sum(ep.rewards), rtol=0, atol=1e-9)
        replay = replay_episode(env, ep.qpos, ep.qvel, ep.actions, seed=11)
        for key in ("obs", "next_obs", "rewards", "absorbing"):
            assert np.array_equal(replay[key], getattr(ep, key)), key
    finally:
        env.stop()


def test_unrecorded_episode_keeps_only_the_outcome():
    env = CountingEnv(fall_at=None)
    ep = run_episode(env, HookedPolicy(), seed=0, horizon=2)
    assert ep.obs is None and ep.actions is None and ep.qpos is None
    with pytest.raises(ValueError, match="record=True"):
        ep.forward_speed(0.01)
