"""Partially observable variants: `.pomdp` Task-IDs and `hide=` remove exactly the named observation entries."""
from __future__ import annotations

import numpy as np
import pytest

from loco_il.environments import LocoEnv


def _state_after_random_steps(env, n=15, seed=0):
    rng = np.random.default_rng(seed)
    env.reset()
    for _ in range(n):
        env.step(rng.uniform(-1, 1, env.model.nu))
    return env.get_sim_state()


@pytest.mark.parametrize("body", ["Hopper", "Walker2d"])
def test_pomdp_observes_positions_only(body):
    full = LocoEnv.make(f"{body}.run.perfect", seed=0)
    pomdp = LocoEnv.make(f"{body}.run.perfect.pomdp", seed=0)
    assert pomdp.pomdp and pomdp.task_id == f"{body}.run.perfect.pomdp"
    positions = [n for n, g in zip(full.obs_spec.names, full.obs_spec.groups) if g == "positions"]
    velocities = [n for n, g in zip(full.obs_spec.names, full.obs_spec.groups) if g == "velocities"]
    assert velocities and list(pomdp.obs_spec.names) == positions
    assert not set(velocities) & set(pomdp.obs_spec.names)
    assert pomdp.obs_spec.dim == len(positions) == pomdp.info.observation_space.shape[0]
    assert pomdp.reset().shape == (len(positions),)
    if body == "Hopper":
        assert pomdp.obs_spec.names == ("q_rootz", "q_rooty", "q_thigh_joint", "q_leg_joint", "q_foot_joint")

    qpos, qvel = _state_after_random_steps(full)
    assert np.abs(qvel).max() > 1e-3                     # velocities are not trivially zero
    full_obs = full.set_sim_state(qpos, qvel)
    idx = [full.obs_spec.index(n) for n in pomdp.obs_spec.names]
    np.testing.assert_array_equal(pomdp.set_sim_state(qpos, qvel), full_obs[idx])
    # stepping from the same state with the same action keeps them consistent (up to solver warm-start)
    action = np.full(full.model.nu, 0.3)
    np.testing.assert_allclose(pomdp.step(action)[0], full.step(action)[0][idx], rtol=0, atol=1e-9)


def test_hide_velocities_equals_pomdp():
    hidden = LocoEnv.make("Hopper.run.perfect", hide=("velocities",))
    pomdp = LocoEnv.make("Hopper.run.perfect.pomdp")
    assert hidden.obs_spec.names == pomdp.obs_spec.names


def test_hide_single_entry():
    full = LocoEnv.make("Hopper.run.perfect", seed=0)
    env = LocoEnv.make("Hopper.run.perfect", hide=("q_rootz", "dq_rootx"))
    assert "q_rootz" not in env.obs_spec.names and "dq_rootx" not in env.obs_spec.names
    assert env.obs_spec.dim == full.obs_spec.dim - 2
    qpos, qvel = _state_after_random_steps(full, seed=1)
    full_obs = full.set_sim_state(qpos, qvel)
    keep = [i for i, n in enumerate(full.obs_spec.names) if n not in ("q_rootz", "dq_rootx")]
    np.testing.assert_array_equal(env.set_sim_state(qpos, qvel), full_obs[keep])
    both = LocoEnv.make("Hopper.run.perfect.pomdp", hide=("q_rootz",))
    assert both.obs_spec.names == ("q_rooty", "q_thigh_joint", "q_leg_joint", "q_foot_joint")


def test_unknown_hidden_name_raises():
    with pytest.raises(KeyError, match="q_rootzz"):
        LocoEnv.make("Hopper.run.perfect", hide=("q_rootzz",))
