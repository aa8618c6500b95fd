"""Retargeting human motion to robots (IK).

Core tests synthesize a small walking clip on DeepMimic's humanoid skeleton; the others use the motion
files shipped in the package (DeepMimic walk). The `real` datasets built from retargeted clips are tested in
tests/datasets/test_real.py.

Documented bounds (see loco_il/motion/mocap/retarget.py): mean keypoint error below 0.08 m,
no sole point more than 1 cm below the ground, every limited joint inside its range.
"""
from __future__ import annotations

import numpy as np
import pytest

from loco_il.motion.mocap import load_deepmimic
from loco_il.motion.mocap.clips import PACKAGED_MOCAP
from loco_il.motion.mocap.retarget import (
    RetargetOptions,
    RobotKinematics,
    align_heading,
    detect_contacts,
    loop_keypoints,
    retarget_clip,
    retarget_robot_to_robot,
)
from loco_il.motion.mocap.robot_maps import ROBOT_MAPS, get_robot_map, parse_point
from retarget_common import KEYPOINT_BOUND, PENETRATION_BOUND, cached_env, synthetic_walk

WALK = PACKAGED_MOCAP / "deepmimic" / "humanoid3d_walk.txt"


def _task_of(body: str) -> str:
    return "Humanoid.run.perfect" if body == "Humanoid" else f"{body}.walk.real"


def _check_quality(env, res) -> None:
    m = res.metrics
    assert res.qpos.shape == (m["frames"], env.model.nq) and res.qvel.shape == (m["frames"], env.model.nv)
    assert np.isfinite(res.qpos).all() and np.isfinite(res.qvel).all()
    assert m["in_limits_fraction"] == 1.0
    assert m["keypoint_error_m"] < KEYPOINT_BOUND, m
    assert m["penetration_max_m"] <= PENETRATION_BOUND, m
    kin = RobotKinematics(env)
    assert kin.in_limits(res.qpos).all()
    lowest = []
    for q in res.qpos:
        kin.forward(q)
        lowest.append(kin.sole_heights().min())
    assert min(lowest) >= -PENETRATION_BOUND
    assert abs(float(np.median(lowest))) < 0.03          # the feet are on the floor, not floating


# ----------------------------------------------------------------------------- pieces


def test_loop_keypoints_is_continuous_and_advances():
    t = np.arange(31) / 30.0
    walk = {"l_hip": np.stack([t, np.full_like(t, 0.1), 0.9 + 0.01 * np.sin(2 * np.pi * t)], -1),
            "r_hip": np.stack([t, np.full_like(t, -0.1), 0.9 + 0.01 * np.sin(2 * np.pi * t)], -1),
            "l_ankle": np.stack([t + 0.05 * np.sin(2 * np.pi * t), np.full_like(t, 0.1), 0.1 + 0.03 * t], -1)}
    out = loop_keypoints(walk, 3)
    assert out["l_hip"].shape == (91, 3)
    assert out["l_hip"][-1, 0] == pytest.approx(3.0)                 # three cycles of 1 m
    step = np.linalg.norm(np.diff(out["l_ankle"], axis=0), axis=1)
    assert step.max() < 3 * np.median(step) + 1e-6                    # no jump at the seams (0.03 m mismatch)


def test_align_heading_turns_travel_to_plus_x():
    t = np.linspace(0, 2, 50)
    d = np.array([np.cos(1.0), np.sin(1.0), 0.0])
    left = np.array([-np.sin(1.0), np.cos(1.0), 0.0]) * 0.1
    kp = {"l_hip": 5 + t[:, None] * d + left, "r_hip": 5 + t[:, None] * d - left}
    out, yaw = align_heading(kp)
    hc = 0.5 * (out["l_hip"] + out["r_hip"])
    assert yaw == pytest.approx(-1.0)
    np.testing.assert_allclose(hc[0, :2], 0.0, atol=1e-12)
    np.testing.assert_allclose(hc[-1, :2], [2.0, 0.0], atol=1e-9)
    assert out["l_hip"][0, 1] > out["r_hip"][0, 1]                    # left stays left


def test_detect_contacts_finds_the_stance():
    fps, t = 100.0, np.arange(100) / 100.0
    stance = t < 0.5
    x = np.where(stance, 0.0, 2.0 * (t - 0.5))
    z = np.where(stance, 0.08, 0.08 + 0.2 * np.sin(np.pi * (t - 0.5) / 0.5))
    kp = {"l_ankle": np.stack([x, np.zeros_like(x), z], -1),
          "r_ankle": np.stack([np.zeros_like(x), np.full_like(x, -0.2), np.full_like(x, 0.08)], -1)}
    c = detect_contacts(kp, fps, leg=0.8)
    assert c["r_ankle"].all()
    assert c["l_ankle"][:45].all() and not c["l_ankle"][60:].any()


def test_every_map_resolves_on_its_robot():
    assert {"UnitreeH1", "UnitreeG1", "Atlas", "Talos", "HumanoidTorque", "HumanoidMuscle", "H1", "G1", "MyoLeg",
            "BoosterT1", "Humanoid"} <= set(ROBOT_MAPS)
    for name, rmap in ROBOT_MAPS.items():
        for spec in rmap.keypoints.values():
            parse_point(spec)
        assert {"l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle"} <= set(rmap.keypoints)
    with pytest.raises(KeyError, match="no keypoint map"):
        get_robot_map("UnitreeA1")


@pytest.mark.parametrize("body", sorted(ROBOT_MAPS))
def test_synthetic_walk_on_every_robot(body):
    env = cached_env(_task_of(body))
    kin = RobotKinematics(env)
    top = max(kin.data.xpos[:, 2].max(), max(v[2] for v in kin.rest.values()))
    assert 0.6 * top < kin.map.height < 1.4 * top + 0.2          # the map's height is the robot's
    assert kin.rest["l_hip"][1] > kin.rest["r_hip"][1]              # faces +x, left at +y
    res = retarget_clip(env, synthetic_walk(duration=1.0), kinematics=kin)
    _check_quality(env, res)


def test_velocities_are_finite_differences():
    env = cached_env("Humanoid.run.perfect")
    res = retarget_clip(env, synthetic_walk())
    import mujoco
    v = np.zeros(env.model.nv)
    mujoco.mj_differentiatePos(env.model, v, 2 * env.dt, res.qpos[9], res.qpos[11])
    np.testing.assert_allclose(res.qvel[10], v, atol=1e-9)


def test_robot_to_robot():
    src, dst = cached_env("Humanoid.run.perfect"), cached_env(_task_of("UnitreeH1"))
    first = retarget_clip(src, synthetic_walk())
    res = retarget_robot_to_robot(src, first.qpos, dst)
    assert res.n_frames == int(round((first.n_frames - 1) * src.dt / dst.dt)) + 1
    _check_quality(dst, res)


def test_uniform_mode_and_options():
    env = cached_env("Humanoid.run.perfect")
    res = retarget_clip(env, synthetic_walk(), options=RetargetOptions(mode="uniform", iterations=4))
    assert res.metrics["in_limits_fraction"] == 1.0 and res.metrics["penetration_max_m"] <= PENETRATION_BOUND
    with pytest.raises(ValueError, match="mode"):
        retarget_clip(env, synthetic_walk(), options=RetargetOptions(mode="bogus"))


@pytest.mark.parametrize("body", ["UnitreeH1", "G1"])
def test_deepmimic_walk_to_two_robots(body):
    env = cached_env(_task_of(body))
    clip = load_deepmimic(WALK)
    res = retarget_clip(env, clip, n_cycles=2)
    _check_quality(env, res)
    assert res.metrics["contact_fraction"] > 0.3                       # walking: a foot is mostly down
    assert res.metrics["foot_sliding_mps"] < 0.1
    hc = 0.5 * (res.robot_points["l_hip"] + res.robot_points["r_hip"])
    speed = (hc[-1, 0] - hc[0, 0]) / ((res.n_frames - 1) * env.dt)
    assert 0.5 < speed < 1.5                                           # ~1 m/s walk, scaled to the robot, along +x
