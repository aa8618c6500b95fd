"""Gait generator for the quadrupeds' `real` data: leg IK, CPG, walking quality in the envs, dataset format."""
from __future__ import annotations

import mujoco
import numpy as np
import pytest

from loco_il.datasets import Trajectories, create_dataset
from loco_il.datasets.gait import (GaitParams, PhaseOscillators, TrotController, is_quadruped,
                                   leg_fk, leg_ik, leg_jacobian, quadruped_legs, quadruped_real_dataset,
                                   quadruped_real_provider, real_dispatcher, run_gait_episode)
from loco_il.datasets.gait.controller import wrap_angle
from loco_il.datasets.gait.cpg import swing_position
from loco_il.datasets.providers import register_real_provider, registered_providers, unregister_provider
from loco_il.environments.registry import get_body, make

QUADRUPEDS = ("UnitreeA1", "UnitreeGo1")
GOAL_SPEED = 0.5


@pytest.fixture(scope="module")
def envs():
    cache = {}

    def get(task_id):
        if task_id not in cache:
            cache[task_id] = make(task_id)
        return cache[task_id]
    return get


def seed_with_command(env, lo, hi):
    """The first reset seed whose sampled direction lies in [lo, hi] (radians)."""
    for seed in range(500):
        env.seed(seed)
        env.reset()
        if lo <= float(env.command[0]) <= hi:
            return seed
    raise AssertionError("no seed gives such a command")


# ----------------------------------------------------------------------------- kinematics
@pytest.mark.parametrize("body", QUADRUPEDS)
def test_leg_kinematics_match_mujoco(envs, body):
    env = envs(f"{body}.simple.real")
    model, data = env.model, env.data
    legs = quadruped_legs(model)
    assert [leg.name for leg in legs] == ["FR", "FL", "RR", "RL"]
    trunk = int(model.jnt_bodyid[0])
    rng = np.random.default_rng(0)
    env.reset()
    for leg in legs:
        for _ in range(20):
            q = rng.uniform([-0.5, -0.3, -2.4], [0.5, 1.5, -1.0])
            data.qpos[leg.qpos_adr] = q
            mujoco.mj_kinematics(model, data)
            R = data.xmat[trunk].reshape(3, 3)
            foot = R.T @ (data.geom_xpos[leg.foot_geom] - data.xpos[trunk]) - leg.hip_pos
            np.testing.assert_allclose(leg_fk(leg, q), foot, atol=1e-9)
            x_plane = -leg.l1 * np.cos(q[1]) - leg.l2 * np.cos(q[1] + q[2])
            if x_plane < -0.05:      # foot below the hip in the leg plane: the IK's (walking) branch
                np.testing.assert_allclose(leg_ik(leg, foot, clip=False), q, atol=1e-7)
            numeric = np.stack([(leg_fk(leg, q + 1e-6 * e) - leg_fk(leg, q - 1e-6 * e)) / 2e-6 for e in np.eye(3)], 1)
            np.testing.assert_allclose(leg_jacobian(leg, q), numeric, atol=1e-7)
    # out of reach: the foot lands on the workspace boundary, joints stay in range
    q = leg_ik(legs[0], np.array([0.0, legs[0].d, -1.0]))
    assert np.all(q >= legs[0].q_lo) and np.all(q <= legs[0].q_hi)


def test_actuator_modes(envs):
    assert not TrotController(envs("UnitreeA1.simple.real")).position_servo    # torque motors, PD in the loop
    assert TrotController(envs("UnitreeGo1.simple.real")).position_servo       # position servos


# ----------------------------------------------------------------------------- CPG
def test_oscillators_converge_to_trot():
    params = GaitParams(frequency=2.5, duty=0.5, coupling=4.0)
    osc = PhaseOscillators(params, initial=np.array([0.0, 0.3, 0.8, 0.2]))
    assert osc.pattern_error() > 0.15
    stance = []
    for _ in range(600):                       # 6 s at 100 Hz
        osc.step(0.01)
        stance.append(osc.in_stance())
    assert osc.pattern_error() < 0.01
    stance = np.array(stance[-200:])
    assert np.all(stance[:, 0] == stance[:, 3]) and np.all(stance[:, 1] == stance[:, 2])   # diagonal pairs
    assert np.all(stance[:, 0] != stance[:, 1])                                             # pairs alternate
    assert abs(stance.mean() - params.duty) < 0.03
    # the phase advances at the gait frequency once locked
    p0 = osc.phase.copy()
    osc.step(0.4)
    np.testing.assert_allclose(osc.phase - p0, 1.0, atol=1e-3)


def test_swing_trajectory_endpoints():
    a, b = np.array([-0.05, 0.1]), np.array([0.06, 0.12])
    xy, z = swing_position(0.0, a, b, 0.08)
    np.testing.assert_allclose(xy, a)
    assert z == pytest.approx(0.0)
    xy, z = swing_position(1.0, a, b, 0.08)
    np.testing.assert_allclose(xy, b)
    assert z == pytest.approx(0.0, abs=1e-12)
    assert swing_position(0.5, a, b, 0.08)[1] == pytest.approx(0.08)


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
