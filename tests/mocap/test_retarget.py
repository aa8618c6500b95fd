"""Retargeting human motion to robots (IK) and the `real` datasets built from it.

Core tests synthesize a small walking clip on DeepMimic's humanoid skeleton; the others use the motion
files shipped in the package (DeepMimic walk, the `real` provider).

Documented bounds (see loco_il/datasets/mocap/retarget.py): mean keypoint error below 0.08 m,
no sole point more than 1 cm below the ground, every limited joint inside its range.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from loco_il import LocoEnv
from loco_il.datasets import DatasetError, Trajectories
from loco_il.datasets.mocap import MotionClip, humanoid3d_skeleton, load_deepmimic, quat_from_axis_angle
from loco_il.datasets.mocap.retarget import (
    RetargetOptions,
    RobotKinematics,
    align_heading,
    detect_contacts,
    loop_keypoints,
    result_to_trajectories,
    retarget_clip,
    retarget_robot_to_robot,
)
from loco_il.datasets.mocap.robot_maps import ROBOT_MAPS, get_robot_map, parse_point

from loco_il.datasets.real import PACKAGED_MOCAP  # noqa: E402  (the clips shipped in the package)
WALK = PACKAGED_MOCAP / "deepmimic" / "humanoid3d_walk.txt"

KEYPOINT_BOUND = 0.08      # m, mean keypoint error
PENETRATION_BOUND = 0.01   # m, deepest sole point below the ground

_ENVS: dict = {}


def _env(task_id: str) -> LocoEnv:
    """A cached env; skip when the robot's model files cannot be had (no network, no cache)."""
    if task_id not in _ENVS:
        from loco_il.environments.assets import AssetError
        if task_id.split(".")[0] not in {t.split(".")[0] for t in LocoEnv.get_all_task_names()}:
            pytest.skip(f"{task_id.split('.')[0]} is not registered in this checkout")
        try:
            _ENVS[task_id] = LocoEnv.make(task_id)
        except AssetError as exc:
            pytest.skip(f"model files of {task_id} unavailable: {exc}")
    return _ENVS[task_id]


def _task_of(body: str) -> str:
    return "Humanoid.run.perfect" if body == "Humanoid" else f"{body}.walk.real"


def synthetic_walk(duration: float = 1.5, fps: float = 30.0, speed: float = 1.0, period: float = 1.0) -> MotionClip:
    """A crude walking motion on DeepMimic's humanoid skeleton (z up, x forward, metres)."""
    sk = humanoid3d_skeleton()
    t = np.arange(int(round(duration * fps)) + 1) / fps
    n, j = len(t), sk.n_joints
    quats = np.zeros((n, j, 4))
    quats[..., 0] = 1.0
    back = np.array([0.0, -1.0, 0.0])      # rotating about -y by a positive angle swings a limb forward
    for side, shift in (("l", 0.0), ("r", np.pi)):
        phase = 2 * np.pi * t / period + shift
        hip = 0.35 * np.sin(phase)
        knee = 0.1 + 0.6 * np.maximum(0.0, np.sin(phase + 0.5 * np.pi)) ** 2
        quats[:, sk.index(f"{side}_hip")] = quat_from_axis_angle(back, hip)
        quats[:, sk.index(f"{side}_knee")] = quat_from_axis_angle(sk.hinge_axes[sk.index(f"{side}_knee")], -knee)
        quats[:, sk.index(f"{side}_ankle")] = quat_from_axis_angle(back, -(hip - knee))
        quats[:, sk.index(f"{side}_shoulder")] = quat_from_axis_angle(back, -0.3 * np.sin(phase))
        quats[:, sk.index(f"{side}_elbow")] = quat_from_axis_angle(sk.hinge_axes[sk.index(f"{side}_elbow")], 0.3)
    root_pos = np.stack([speed * t, np.zeros(n), 0.86 + 0.02 * np.cos(4 * np.pi * t / period)], -1)
    root_quat = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    return MotionClip(skeleton=sk, fps=fps, root_pos=root_pos, root_quat=root_quat, joint_quats=quats,
                      name="synthetic_walk")


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
    env = _env(_task_of(body))
    kin = RobotKinematics(env)
    top = max(kin.data.xpos[:, 2].max(), max(v[2] for v in kin.rest.values()))
    assert 0.6 * top < kin.map.height < 1.4 * top + 0.2          # the map's height is the robot's
    assert kin.rest["l_hip"][1] > kin.rest["r_hip"][1]              # faces +x, left at +y
    res = retarget_clip(env, synthetic_walk(duration=1.0), kinematics=kin)
    _check_quality(env, res)


def test_dataset_from_retargeted_clip_validates_and_round_trips(tmp_path):
    env = _env("Humanoid.run.perfect")
    res = retarget_clip(env, synthetic_walk())
    data = result_to_trajectories(env, [res, res], info={"source": "synthetic"})
    assert data.actions is None and data.obs.shape[1] == env.obs_spec.dim
    assert data.info["dataset_type"] == "real" and data.info["obs_names"] == list(env.obs_spec.names)
    assert data.n_trajectories == 2 and not data.absorbing.any()
    np.testing.assert_array_equal(data.obs[1:res.n_frames - 1], data.next_obs[:res.n_frames - 2])
    path = data.save(tmp_path / "real.npz")
    back = Trajectories.load(path)
    np.testing.assert_array_equal(back.obs, data.obs)
    np.testing.assert_array_equal(back.next_obs, data.next_obs)
    assert back.info == data.info
    # the observation is the env's: replaying a state gives the stored observation
    np.testing.assert_allclose(env.set_sim_state(res.qpos[3], res.qvel[3]), data.obs[3])


def test_velocities_are_finite_differences():
    env = _env("Humanoid.run.perfect")
    res = retarget_clip(env, synthetic_walk())
    import mujoco
    v = np.zeros(env.model.nv)
    mujoco.mj_differentiatePos(env.model, v, 2 * env.dt, res.qpos[9], res.qpos[11])
    np.testing.assert_allclose(res.qvel[10], v, atol=1e-9)


def test_robot_to_robot():
    src, dst = _env("Humanoid.run.perfect"), _env(_task_of("UnitreeH1"))
    first = retarget_clip(src, synthetic_walk())
    res = retarget_robot_to_robot(src, first.qpos, dst)
    assert res.n_frames == int(round((first.n_frames - 1) * src.dt / dst.dt)) + 1
    _check_quality(dst, res)


def test_uniform_mode_and_options():
    env = _env("Humanoid.run.perfect")
    res = retarget_clip(env, synthetic_walk(), options=RetargetOptions(mode="uniform", iterations=4))
    assert res.metrics["in_limits_fraction"] == 1.0 and res.metrics["penetration_max_m"] <= PENETRATION_BOUND
    with pytest.raises(ValueError, match="mode"):
        retarget_clip(env, synthetic_walk(), options=RetargetOptions(mode="bogus"))


# ----------------------------------------------------------------------------- the real provider


def test_missing_motion_files_error(tmp_path, monkeypatch):
    from loco_il.datasets.real import MotionFilesMissingError
    env = _env("UnitreeH1.walk.real")
    user = tmp_path / "my_clips"
    user.mkdir()
    monkeypatch.setenv("LOCO_IL_MOCAP", str(user))
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path / "datasets"))
    with pytest.raises(MotionFilesMissingError) as info:
        env.create_dataset(clips=["cmu_bvh/01_01.bvh"], verbose=False)
    msg = str(info.value)
    assert "01_01.bvh" in msg and str(user) in msg and "LOCO_IL_MOCAP" in msg
    assert isinstance(info.value, DatasetError)


def test_user_mocap_folder_adds_clips(tmp_path, monkeypatch):
    """$LOCO_IL_MOCAP adds clips: a file there is found, and the task's own clips still come from the package."""
    from loco_il.datasets.real import PACKAGED_MOCAP, find_motion_files, ClipSpec
    user = tmp_path / "my_clips"
    (user / "mine").mkdir(parents=True)
    own = user / "mine" / "walk_copy.txt"
    own.write_bytes((PACKAGED_MOCAP / "deepmimic" / "humanoid3d_walk.txt").read_bytes())
    monkeypatch.setenv("LOCO_IL_MOCAP", str(user))
    assert find_motion_files([ClipSpec("mine/walk_copy.txt")]) == [own]
    assert find_motion_files([ClipSpec("deepmimic/humanoid3d_walk.txt")]) == [
        PACKAGED_MOCAP / "deepmimic" / "humanoid3d_walk.txt"]


def test_tasks_and_bodies_without_motion_are_explained(tmp_path, monkeypatch):
    from loco_il.datasets.providers import ProviderUnavailableError
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path))
    with pytest.raises(ProviderUnavailableError, match="no motion capture is mapped to the task 'stand'"):
        _env("UnitreeH1.stand.real").create_dataset(verbose=False)
    # quadrupeds' real data come from the gait generator (the dispatcher); the mocap provider itself refuses them
    from loco_il.datasets.real import real_provider
    with pytest.raises(ProviderUnavailableError, match="keypoint map"):
        real_provider(_env("UnitreeA1.simple.real"), verbose=False)



@pytest.mark.parametrize("body", ["UnitreeH1", "G1"])
def test_deepmimic_walk_to_two_robots(body):
    env = _env(_task_of(body))
    clip = load_deepmimic(WALK)
    res = retarget_clip(env, clip, n_cycles=2)
    _check_quality(env, res)
    assert res.metrics["contact_fraction"] > 0.3                       # walking: a foot is mostly down
    assert res.metrics["foot_sliding_mps"] < 0.1
    hc = 0.5 * (res.robot_points["l_hip"] + res.robot_points["r_hip"])
    speed = (hc[-1, 0] - hc[0, 0]) / ((res.n_frames - 1) * env.dt)
    assert 0.5 < speed < 1.5                                           # ~1 m/s walk, scaled to the robot, along +x


def test_real_provider_builds_and_caches(tmp_path, monkeypatch):
    monkeypatch.delenv("LOCO_IL_MOCAP", raising=False)
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path))
    env = LocoEnv.make("UnitreeH1.walk.real")
    data = env.create_dataset(n_episodes=1, verbose=False)
    assert data.actions is None and data.obs.shape[1] == env.obs_spec.dim
    info = data.info
    assert info["dataset_type"] == "real" and info["task_id"] == "UnitreeH1.walk.real" and info["seed"] is None
    assert "MIT" in info["source"] and info["sources"][0]["file"] == "humanoid3d_walk.txt"
    q = info["quality"]
    assert q["keypoint_error_m"] < KEYPOINT_BOUND and q["penetration_max_m"] <= PENETRATION_BOUND
    assert q["in_limits_fraction"] == 1.0 and q["frames"] >= 1000      # repeated to 10 s at 100 Hz
    files = sorted(tmp_path.rglob("real-*.npz"))
    assert len(files) == 2                                             # the dataset and its initial states
    stamp = [f.stat().st_mtime_ns for f in files]
    again = env.create_dataset(n_episodes=1, verbose=False)            # from the cache
    np.testing.assert_array_equal(again.obs, data.obs)
    assert [f.stat().st_mtime_ns for f in files] == stamp
    split = env.create_dataset(n_episodes=1, verbose=False, return_init_states=True)
    init = split[1]
    np.testing.assert_allclose(env.set_sim_state(init.qpos[0], init.qvel[0]), data.obs[0])
