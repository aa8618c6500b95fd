"""The quadrupeds' `real` data: the trot walking in the envs (`run_gait_episode`), dataset format, provider.

The gait generator's pieces (leg IK, CPG, actuator modes) are tested in tests/motion/gait."""
from __future__ import annotations

import numpy as np
import pytest

from loco_il.datasets import Trajectories, create_dataset
from loco_il.datasets.gait import quadruped_real_dataset, quadruped_real_provider, real_dispatcher, run_gait_episode
from loco_il.datasets.providers import register_real_provider, registered_providers, unregister_provider
from loco_il.environments.registry import get_body, make
from loco_il.motion.gait import TrotController, is_quadruped
from loco_il.motion.gait.controller import wrap_angle

QUADRUPEDS = ("UnitreeA1", "UnitreeGo1")
GOAL_SPEED = 0.5



def seed_with_command(env, lo, hi):
    """The first reset seed whose sampled direction lies in [lo, hi] (radians)."""
    for seed in range(500):
        env.seed(seed)
        env.reset()
        if lo <= float(env.command[0]) <= hi:
            return seed
    raise AssertionError("no seed gives such a command")


# ----------------------------------------------------------------------------- walking in the env
@pytest.mark.parametrize("body", QUADRUPEDS)
def test_walks_straight_simple(envs, body):
    env = envs(f"{body}.simple.real")
    ep = run_gait_episode(env, 0, episode_steps=500, warmup=0.0)      # 5 s from the reset pose
    assert not ep.terminated and not ep.diverged and ep.obs.shape == (500, env.obs_spec.dim)
    assert abs(ep.metrics["forward_speed"] - GOAL_SPEED) <= 0.4 * GOAL_SPEED, ep.metrics
    assert ep.metrics["direction_error_deg"] < 10.0, ep.metrics
    assert ep.metrics["heading_error_deg"] < 10.0, ep.metrics
    assert ep.metrics["foot_slip"] < 0.15, ep.metrics
    assert np.abs(env.data.ctrl).max() <= np.abs(env.model.actuator_ctrlrange).max() + 1e-12


@pytest.mark.parametrize("body", QUADRUPEDS)
def test_walks_toward_command_hard(envs, body):
    env = envs(f"{body}.hard.real")
    ranges = [(-np.pi, -2.3), (1.2, 2.0), (-0.8, 0.8)]    # behind, to the left, ahead
    for lo, hi in ranges:
        seed = seed_with_command(env, lo, hi)
        ep = run_gait_episode(env, seed, episode_steps=500, warmup=0.0)
        theta = float(ep.command[0])
        assert not ep.terminated and not ep.diverged, (seed, theta, ep.metrics)
        assert ep.metrics["direction_error_deg"] < 30.0, (seed, theta, ep.metrics)
        assert abs(ep.metrics["speed"] - GOAL_SPEED) <= 0.4 * GOAL_SPEED, (seed, theta, ep.metrics)
        # the trunk ends up facing the command
        heading = TrotController(env).heading()
        assert abs(np.degrees(wrap_angle(heading - theta))) < 15.0


# ----------------------------------------------------------------------------- dataset
def test_real_dataset_format_and_replay(envs):
    env = envs("UnitreeA1.hard.real")
    data, init = quadruped_real_dataset(env, n_episodes=2, seed=3, episode_steps=60, warmup=0.5,
                                        return_init_states=True)
    assert isinstance(data, Trajectories) and data.actions is None
    assert data.n_trajectories == 2 and data.n_transitions == 120
    assert data.info["dataset_type"] == "real" and data.info["task_id"] == "UnitreeA1.hard.real"
    assert data.info["obs_names"] == list(env.full_obs_spec.names)
    assert not data.absorbing.any() and np.flatnonzero(data.last).tolist() == [59, 119]
    np.testing.assert_array_equal(data.obs[1:60], data.next_obs[:59])
    q = data.info["gait_quality"]
    assert q["kept_fraction"] > 0 and q["episodes"] == 2 and np.isfinite(q["mean_foot_slip"])
    # every recorded observation is the env's own: the start state gives the first observation,
    # and the command features are the episode's command
    names = list(env.full_obs_spec.names)
    for i, (seed, cmd) in enumerate(zip(data.info["episode_seeds"], data.info["episode_commands"])):
        env.seed(seed)
        env.reset()
        assert env.command.tolist() == cmd
        obs0 = env.set_sim_state(init.qpos[i], init.qvel[i])
        np.testing.assert_allclose(data.obs[60 * i], obs0, atol=1e-12)
        assert data.obs[60 * i, names.index("cmd_cos")] == pytest.approx(np.cos(cmd[0]))
    # the same seed gives the same data
    again = quadruped_real_dataset(env, n_episodes=2, seed=3, episode_steps=60, warmup=0.5)
    np.testing.assert_array_equal(again.obs, data.obs)


def test_provider_caches_and_dispatches(envs, tmp_path, monkeypatch):
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path))
    env = envs("UnitreeGo1.simple.real")
    kwargs = dict(n_episodes=1, generation_seed=0, verbose=False, episode_steps=30, warmup=1.0)
    data, init = quadruped_real_provider(env, **kwargs)
    files = sorted(p.name for p in tmp_path.rglob("*.npz"))
    assert len(files) == 2 and any(f.endswith(".init_states.npz") for f in files)
    again, _ = quadruped_real_provider(env, **kwargs)           # from the cache
    np.testing.assert_array_equal(again.obs, data.obs)
    assert len(init) == 1
    # dispatch: quadrupeds come here, everything else goes to the other provider
    calls = []
    provider = real_dispatcher(lambda e, **kw: calls.append(e) or "other")
    assert provider(env, **kwargs)[0].n_transitions == 30 and not calls
    humanoid = get_body("UnitreeH1")
    assert provider(humanoid) == "other" and calls == [humanoid]
    assert is_quadruped(env) and is_quadruped(get_body("UnitreeA1")) and not is_quadruped(humanoid)
    assert is_quadruped("UnitreeA1.hard.real.pomdp") and not is_quadruped("UnitreeH1.walk.real")
    with pytest.raises(TypeError):
        quadruped_real_provider(env, n_episodes=1, bogus=1)
    # through create_dataset (the registry's `real` provider wrapped by the dispatcher): masks applied
    saved = registered_providers().get("real")
    register_real_provider(real_dispatcher(saved), replace=True)
    try:
        pomdp = make("UnitreeGo1.simple.real.pomdp")
        got = create_dataset(pomdp, **kwargs)
        assert got.obs_dim == pomdp.obs_spec.dim < env.full_obs_spec.dim and got.actions is None
        np.testing.assert_array_equal(got.obs, data.obs[:, pomdp.obs_mask])     # same cached file
    finally:
        if saved is None:
            unregister_provider("real")
        else:
            register_real_provider(saved, replace=True)


def test_pomdp_env_gets_full_observations(envs):
    env = make("UnitreeA1.simple.real.pomdp")
    data = quadruped_real_dataset(env, n_episodes=1, seed=0, episode_steps=20, warmup=0.2, speed_tolerance=1.0)
    assert data.obs_dim == env.full_obs_spec.dim > env.obs_spec.dim


def test_rejects_non_quadrupeds():
    with pytest.raises(ValueError, match="not a quadruped"):
        quadruped_real_dataset(make("Hopper.run.perfect"), n_episodes=1)
