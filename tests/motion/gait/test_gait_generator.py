"""Gait generator of the quadrupeds: leg kinematics against MuJoCo, actuator modes, the CPG's trot and the swing
trajectory. Walking quality in the envs and the `real` datasets: tests/datasets/test_gait.py."""
from __future__ import annotations

import mujoco
import numpy as np
import pytest

from loco_il.motion.gait import (GaitParams, PhaseOscillators, TrotController, leg_fk, leg_ik, leg_jacobian,
                                 quadruped_legs)
from loco_il.motion.gait.cpg import swing_position

QUADRUPEDS = ("UnitreeA1", "UnitreeGo1")



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
