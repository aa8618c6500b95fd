"""LocoMuJoCo 0.4.1's own robots: dimensions, timing, standing start, fall termination.

Published defaults (LocoMuJoCo 0.4.1 docs/docstrings): observation / action dimensions
Atlas 30/10, Talos 34/12, UnitreeH1 32/11, UnitreeG1 56/23, HumanoidTorque 36/13,
HumanoidMuscle 36/92, UnitreeA1 37/12; timestep 1 ms, 10 substeps, horizon 1000.
"""
import time

import numpy as np
import pytest

from loco_il import LocoEnv
from loco_il.environments.bodies.locomujoco.common import RootJointFall
from loco_il.environments.registry import get_body
from loco_il.environments.tasks import StepContext

DIMS = {"Atlas": (30, 10), "Talos": (34, 12), "UnitreeH1": (32, 11), "UnitreeG1": (56, 23),
        "HumanoidTorque": (36, 13), "HumanoidMuscle": (36, 92), "UnitreeA1": (37, 12)}
TASKS = {"Atlas": {"walk", "carry", "stand"}, "Talos": {"walk", "carry", "stand"},
         "UnitreeH1": {"walk", "run", "carry", "stand"},
         "UnitreeG1": {"walk", "run", "stand"}, "HumanoidTorque": {"walk", "run", "stand"},
         "HumanoidMuscle": {"walk", "run", "stand"}, "UnitreeA1": {"simple", "hard"}}
ROBOTS = list(DIMS)
TORQUE_ROBOTS = [r for r in ROBOTS if r != "HumanoidMuscle"]

_ENVS: dict[str, LocoEnv] = {}


def _env(robot: str) -> LocoEnv:
    if robot not in _ENVS:
        _ENVS[robot] = LocoEnv.make(robot, seed=0)
    return _ENVS[robot]


def _hold_still(env: LocoEnv, q0: np.ndarray, kp: float = 1.0, kd: float = 0.01) -> np.ndarray:
    """A joint-space PD action (normalized units) that holds each actuated joint at its start angle."""
    m, d = env.model, env.data
    joints = m.actuator_trnid[:, 0]
    qadr, vadr = m.jnt_qposadr[joints], m.jnt_dofadr[joints]
    return np.clip(kp * (q0[qadr] - d.qpos[qadr]) - kd * d.qvel[vadr], -1.0, 1.0)


@pytest.mark.parametrize("robot", ROBOTS)
def test_dims_timing_and_metadata(robot):
    env = _env(robot)
    obs = env.reset()
    body = get_body(robot)
    assert (obs.shape[0], env.info.action_space.shape[0]) == DIMS[robot]
    assert env.obs_spec.dim == DIMS[robot][0]
    assert env.model.opt.timestep == pytest.approx(0.001) and env.n_substeps == 10
    assert env.dt == pytest.approx(0.01) and env.info.horizon == 1000
    assert set(body.tasks) == TASKS[robot]
    assert body.default_task == ("simple" if robot == "UnitreeA1" else "walk")
    assert body.default_dataset == "real" and tuple(body.datasets) == ("real", "perfect", "preference")
    assert body.family == ("quadruped" if robot == "UnitreeA1" else "humanoid")
    assert body.licence
    # LocoMuJoCo drops the two horizontal root slides; the first entry is the vertical one
    vertical, horizontal = (("q_trunk_tz", {"q_trunk_tx", "q_trunk_ty"}) if robot == "UnitreeA1"
                            else ("q_pelvis_ty", {"q_pelvis_tx", "q_pelvis_tz"}))
    assert env.obs_spec.names[0] == vertical and not horizontal & set(env.obs_spec.names), (
        "observations.horizontal_root_qpos must use the slide axis in world coordinates (the humanoid "
        "pelvis body is rotated 90 deg about x, so pelvis_ty is vertical)")


def test_unitree_a1_command_features():
    simple = LocoEnv.make("UnitreeA1.simple", seed=0)
    obs = simple.reset()
    assert simple.obs_spec.names[-3:] == ("cmd_cos", "cmd_sin", "cmd_speed")
    np.testing.assert_allclose(obs[-3:], [1.0, 0.0, 0.5])
    hard = LocoEnv.make("UnitreeA1.hard", seed=3)
    angles = []
    for _ in range(3):
        obs = hard.reset()
        angles.append(np.arctan2(obs[-2], obs[-3]))
        assert obs[-1] == 0.5 and np.hypot(obs[-3], obs[-2]) == pytest.approx(1.0)
    assert np.ptp(angles) > 1e-3


def test_removed_joints_match_locomujoco_defaults():
    removed = {name: len(get_body(name).joints_to_remove) for name in ROBOTS}
    assert removed == {"Atlas": 15, "Talos": 12, "UnitreeH1": 8, "UnitreeG1": 0, "HumanoidTorque": 18,
                       "HumanoidMuscle": 18, "UnitreeA1": 0}
    env = _env("HumanoidTorque")
    names = {env.model.joint(j).name for j in range(env.model.njnt)}
    assert not names & {"subtalar_angle_l", "mtp_angle_r", "arm_flex_l", "wrist_dev_r"}
    assert env.model.neq == 1     # only the inactive pelvis weld is left


@pytest.mark.parametrize("robot", ROBOTS)
def test_standing_start_survives_zero_action(robot):
    """Zero torque cannot hold a humanoid up forever; every robot stands for at least 0.2 s (it takes 0.34-0.42 s)."""
    env = _env(robot)
    env.reset()
    root = env.model.jnt_bodyid[0]
    z0 = env.data.xpos[root, 2]
    for _ in range(20):
        _, _, absorbing, info = env.step(np.zeros(env.model.nu))
        assert not absorbing and not info["diverged"]
    assert abs(env.data.xpos[root, 2] - z0) < 0.1


@pytest.mark.parametrize("robot", TORQUE_ROBOTS)
def test_standing_start_is_held_by_a_pd_action(robot):
    """With a hold-still (joint PD) action the torque robots keep standing for 50 steps (0.5 s)."""
    env = _env(robot)
    env.reset()
    q0 = env.data.qpos.copy()
    for _ in range(50):
        _, _, absorbing, _ = env.step(_hold_still(env, q0))
        assert not absorbing


@pytest.mark.parametrize("robot", ROBOTS)
def test_random_actions_survive_a_few_steps(robot):
    env = _env(robot)
    rng = np.random.default_rng(0)
    for _ in range(2):
        env.reset()
        for _ in range(2):
            _, _, absorbing, _ = env.step(rng.uniform(-1, 1, env.model.nu))
            assert not absorbing


@pytest.mark.parametrize("robot", ROBOTS)
def test_fallen_pose_terminates(robot):
    env = _env(robot)
    env.reset()
    m = env.model
    qpos, qvel = env.get_sim_state()
    z_model = m.body_pos[m.jnt_bodyid[0], 2]
    if robot == "UnitreeA1":
        slide, tilt = "trunk_tz", "trunk_list"
    else:
        slide, tilt = "pelvis_ty", "pelvis_tilt"
    qpos[m.joint(slide).qposadr[0]] = 0.12 - z_model           # root body 12 cm above the floor
    qpos[m.joint(tilt).qposadr[0]] = np.pi / 2                  # lying on its back / side
    env.set_sim_state(qpos, np.zeros_like(qvel))
    _, _, absorbing, info = env.step(np.zeros(m.nu))
    assert absorbing and info["terminated"]


def test_yaw_and_back_bounds_follow_locomujoco():
    """LocoMuJoCo also ends an episode when the pelvis turns (Atlas: |rotation| > pi/10) or Talos bends its back."""
    for robot, joint, value in (("Atlas", "pelvis_rotation", 0.4), ("Talos", "back_bky", 0.5)):
        env = _env(robot)
        env.reset()
        qpos, qvel = env.get_sim_state()
        qpos[env.model.joint(joint).qposadr[0]] = value
        env.set_sim_state(qpos, qvel)
        _, _, absorbing, _ = env.step(np.zeros(env.model.nu))
        assert absorbing, (robot, joint)
    a1 = _env("UnitreeA1")          # the quadruped has no yaw bound (its 'hard' task turns)
    a1.reset()
    qpos, qvel = a1.get_sim_state()
    qpos[a1.model.joint("trunk_rotation").qposadr[0]] = 2.0
    a1.set_sim_state(qpos, qvel)
    _, _, absorbing, _ = a1.step(np.zeros(12))
    assert not absorbing


def test_root_joint_fall_bounds_are_closed_intervals():
    term = RootJointFall((0.5, 1.0), (("pelvis_tilt", -0.1, 0.2),))
    env = _env("Atlas")
    env.reset()
    qpos, qvel = env.get_sim_state()
    ctx = StepContext(env.model, env.data, env.dt, np.zeros(10), np.zeros(2), np.zeros(2), np.zeros(0))
    for tilt, fallen in ((0.2, False), (0.2001, True), (-0.1, False), (-0.11, True)):
        qpos[env.model.joint("pelvis_tilt").qposadr[0]] = tilt
        qpos[env.model.joint("pelvis_ty").qposadr[0]] = 0.0
        env.set_sim_state(qpos, qvel)
        assert term(ctx) is fallen, tilt


def test_env_creation_time_after_caching(capsys):
    times = {}
    for robot in ROBOTS:
        _env(robot)                               # first creation fills MuJoCo's mesh cache
        start = time.perf_counter()
        LocoEnv.make(robot)
        times[robot] = time.perf_counter() - start
    with capsys.disabled():
        print("\nLocoMuJoCo robot env creation (s, models cached):",
              ", ".join(f"{k} {v:.2f}" for k, v in times.items()))
    assert max(times.values()) < 2.0              # < 1 s on an idle machine; lenient for loaded CI
