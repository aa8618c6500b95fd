"""Tests for the DeepMimic loader and canonical keypoints."""

import json
from pathlib import Path

import numpy as np
import pytest

from loco_il.motion.mocap import (
    DeepMimicFormatError,
    canonical_keypoints,
    humanoid3d_skeleton,
    load_bvh,
    load_deepmimic,
)
from loco_il.motion.mocap.deepmimic import HUMANOID3D_JOINTS

from loco_il.motion.mocap.clips import PACKAGED_MOCAP  # noqa: E402  (the clips shipped in the package)
DM_DIR = PACKAGED_MOCAP / "deepmimic"

ALL_KEYPOINTS = ["pelvis", "l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle", "l_toe",
                 "r_toe", "torso", "neck", "head", "l_shoulder", "r_shoulder", "l_elbow", "r_elbow",
                 "l_wrist", "r_wrist"]

IDENT = [1.0, 0.0, 0.0, 0.0]


def _need(path: Path) -> Path:
    assert path.is_file(), f"{path} is missing from the package data"
    return path


def _frame(dt, root_pos=(0.0, 0.9, 0.0), root_quat=IDENT, chest=IDENT, neck=IDENT, r_hip=IDENT,
           r_knee=0.0, r_ankle=IDENT, r_shoulder=IDENT, r_elbow=0.0, l_hip=IDENT, l_knee=0.0,
           l_ankle=IDENT, l_shoulder=IDENT, l_elbow=0.0):
    return ([dt, *root_pos, *root_quat, *chest, *neck, *r_hip, r_knee, *r_ankle, *r_shoulder,
             r_elbow, *l_hip, l_knee, *l_ankle, *l_shoulder, l_elbow])


def _write(tmp_path, frames, loop="none", name="motion.txt"):
    p = tmp_path / name
    p.write_text(json.dumps({"Loop": loop, "Frames": frames}))
    return p


# ---------------------------------------------------------------------------
# Synthetic files
# ---------------------------------------------------------------------------
def test_frame_layout(tmp_path):
    s45 = np.sin(np.pi / 4)
    yaw90 = [np.cos(np.pi / 4), 0.0, s45, 0.0]  # 90 deg about DeepMimic +Y (up)
    frames = [
        _frame(0.05, root_pos=(1.0, 0.9, 2.0), chest=yaw90, r_knee=-0.5, l_elbow=0.7),
        _frame(0.05, root_pos=(1.1, 0.9, 2.0), l_knee=-1.0, r_elbow=0.3),
        _frame(0.0, root_pos=(1.2, 0.9, 2.0)),
    ]
    assert len(frames[0]) == 44
    clip = load_deepmimic(_write(tmp_path, frames, loop="wrap"))
    assert clip.n_frames == 3
    assert clip.fps == pytest.approx(20.0)
    assert clip.loop is True
    sk = clip.skeleton
    assert sk.names[:15] == ["pelvis", "chest", "neck", "r_hip", "r_knee", "r_ankle", "r_shoulder",
                             "r_elbow", "r_wrist", "l_hip", "l_knee", "l_ankle", "l_shoulder",
                             "l_elbow", "l_wrist"]
    assert sk.joint_types[:5] == ["free", "ball", "ball", "ball", "hinge"]
    # y-up (x, y, z) -> z-up (x, -z, y)
    np.testing.assert_allclose(clip.root_pos[0], [1.0, -2.0, 0.9])
    # hinge values land on the right joints
    np.testing.assert_allclose(clip.hinge_angle("r_knee"), [-0.5, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(clip.hinge_angle("l_knee"), [0.0, -1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(clip.hinge_angle("l_elbow"), [0.7, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(clip.hinge_angle("r_elbow"), [0.0, 0.3, 0.0], atol=1e-12)

    pos = clip.global_positions()
    root = np.array([1.0, -2.0, 0.9])
    # chest yawed 90 deg about world z: the right shoulder offset (-0.02405, 0.2435, 0.18311)
    # [y-up] = (-0.02405, -0.18311, 0.2435) [z-up] becomes (0.18311, -0.02405, 0.2435)
    chest = root + [0, 0, 0.236151]
    np.testing.assert_allclose(pos[0, sk.index("chest")], chest, atol=1e-12)
    np.testing.assert_allclose(pos[0, sk.index("r_shoulder")], chest + [0.18311, -0.02405, 0.2435],
                               atol=1e-9)
    np.testing.assert_allclose(pos[1, sk.index("r_shoulder")],
                               chest + [0.1 - 0.02405, -0.18311, 0.2435], atol=1e-9)
    # knee flexed by 0.5 rad: the shank swings backwards (-x)
    knee = pos[0, sk.index("r_knee")]
    np.testing.assert_allclose(knee, root + [0, -0.084887, -0.421546], atol=1e-12)
    L = 0.409870
    np.testing.assert_allclose(pos[0, sk.index("r_ankle")],
                               knee + [-L * np.sin(0.5), 0, -L * np.cos(0.5)], atol=1e-12)
    # toe site in front of the ankle, 5 cm below it, in the rest pose
    np.testing.assert_allclose(pos[2, sk.index("l_toe")] - pos[2, sk.index("l_ankle")],
                               [0.1335, 0, -0.05], atol=1e-12)


def test_fps_from_dt_and_loop_flag(tmp_path):
    frames = [_frame(1 / 60)] * 4 + [_frame(0.0)]
    clip = load_deepmimic(_write(tmp_path, frames))
    assert clip.fps == pytest.approx(60.0)
    assert clip.loop is False
    assert clip.duration == pytest.approx(4 / 60)


def test_nonuniform_dt_is_resampled(tmp_path):
    frames = [_frame(0.1, root_pos=(0.0, 0.9, 0.0)), _frame(0.2, root_pos=(1.0, 0.9, 0.0)),
              _frame(0.0, root_pos=(3.0, 0.9, 0.0))]
    with pytest.warns(UserWarning, match="resampling"):
        clip = load_deepmimic(_write(tmp_path, frames))
    assert clip.fps == pytest.approx(1 / 0.15)
    # uniform grid at 0.15 s: x(t) piecewise linear through (0,0), (0.1,1), (0.3,3)
    np.testing.assert_allclose(clip.root_pos[:, 0], [0.0, 1.5, 3.0], atol=1e-9)


@pytest.mark.parametrize(
    "payload,msg",
    [
        ({"Loop": "none", "Frames": [[0.1] * 43]}, "frame 0 has 43 values"),
        ({"Loop": "none"}, "no 'Frames'"),
        ({"Loop": "none", "Frames": []}, "non-empty"),
        ({"Loop": "none", "Frames": [_frame(0.1), _frame(-0.1), _frame(0.0)]}, "non-positive dt"),
        ({"Loop": "none", "Frames": [_frame(0.1, chest=[0, 0, 0, 0])]}, "zero quaternion"),
    ],
)
def test_malformed(tmp_path, payload, msg):
    p = tmp_path / "bad.txt"
    p.write_text(json.dumps(payload))
    with pytest.raises(DeepMimicFormatError, match=msg):
        load_deepmimic(p)


def test_invalid_json_reports_line(tmp_path):
    p = tmp_path / "bad.txt"
    p.write_text('{\n"Loop": "none",\n"Frames": [[1, 2,]]\n}')
    with pytest.raises(DeepMimicFormatError, match=r"bad.txt:3:"):
        load_deepmimic(p)


def test_custom_character_layout(tmp_path):
    def joint(i, name, jtype, parent, y):
        return {"ID": i, "Name": name, "Type": jtype, "Parent": parent, "AttachX": 0, "AttachY": y,
                "AttachZ": 0, "AttachThetaX": 0, "AttachThetaY": 0, "AttachThetaZ": 0}

    char = {"Skeleton": {"Joints": [joint(0, "root", "none", -1, 0),
                                    joint(1, "right_hip", "spherical", 0, 0),
                                    joint(2, "right_knee", "revolute", 1, -0.5),
                                    joint(3, "right_ankle", "fixed", 2, -0.4)]}}
    cp = tmp_path / "char.txt"
    cp.write_text(json.dumps(char))
    frames = [[0.1, 0, 1, 0, *IDENT, *IDENT, -np.pi / 2], [0.0, 0, 1, 0, *IDENT, *IDENT, 0.0]]
    clip = load_deepmimic(_write(tmp_path, frames), character_path=cp)
    assert clip.skeleton.names == ["pelvis", "r_hip", "r_knee", "r_ankle"]
    assert clip.fps == pytest.approx(10.0)
    pos = clip.global_positions()
    np.testing.assert_allclose(pos[0, 3], [-0.4, 0, 0.5], atol=1e-12)  # shank horizontal, behind
    np.testing.assert_allclose(pos[1, 3], [0, 0, 0.1], atol=1e-12)
    # the 44-value humanoid frames do not fit this character
    with pytest.raises(DeepMimicFormatError, match="needs 13"):
        load_deepmimic(_write(tmp_path, [_frame(0.1)], name="m2.txt"), character_path=cp)


def test_builtin_skeleton_matches_documented_numbers():
    sk = humanoid3d_skeleton()
    assert sk.n_source_joints == len(HUMANOID3D_JOINTS) == 15
    # legs: 0.421546 + 0.409870 m, 0.084887 m either side of the pelvis (Y left)
    np.testing.assert_allclose(sk.offsets[sk.index("l_hip")], [0, 0.084887, 0])
    np.testing.assert_allclose(sk.offsets[sk.index("r_knee")], [0, 0, -0.421546])
    np.testing.assert_allclose(sk.hinge_axes[sk.index("r_knee")], [0, -1, 0])


# ---------------------------------------------------------------------------
# Real DeepMimic files from the package data (loco_il/motion/mocap/data)
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def walk():
    return load_deepmimic(_need(DM_DIR / "humanoid3d_walk.txt"))


def test_walk_clip(walk):
    raw = json.loads((DM_DIR / "humanoid3d_walk.txt").read_text())
    assert walk.n_frames == len(raw["Frames"])
    assert walk.fps == pytest.approx(1.0 / raw["Frames"][0][0], rel=1e-4)
    assert walk.fps == 30.0
    assert walk.loop is True
    pelvis_z = walk.root_pos[:, 2]
    assert 0.8 < pelvis_z.mean() < 1.0
    disp = walk.root_pos[-1] - walk.root_pos[0]
    assert disp[0] > 0.5  # forward along +x
    speed = np.linalg.norm(disp[:2]) / walk.duration
    assert 0.8 < speed < 1.6, speed
    for knee in ("l_knee", "r_knee"):
        flexion = -walk.hinge_angle(knee)
        assert np.all(flexion > 0.0) and np.all(flexion < 2.6)
        assert flexion.max() > 0.8  # the swing leg really bends
    for elbow in ("l_elbow", "r_elbow"):
        assert np.all(walk.hinge_angle(elbow) >= 0.0)
    kp = canonical_keypoints(walk, require=ALL_KEYPOINTS)
    feet = np.minimum(kp["l_toe"][:, 2], kp["r_toe"][:, 2])
    assert np.all(np.abs(feet) < 0.1)  # a foot is on the floor in every frame
    assert np.all(kp["head"][:, 2] > 1.3)
    # left is +y
    assert np.all(kp["l_hip"][:, 1] > kp["r_hip"][:, 1])


def test_character_file_matches_builtin(walk):
    char = _need(DM_DIR / "humanoid3d_character.txt")
    clip = load_deepmimic(DM_DIR / "humanoid3d_walk.txt", character_path=char)
    assert clip.skeleton.names == walk.skeleton.names
    np.testing.assert_allclose(clip.global_positions(), walk.global_positions(), atol=1e-12)


@pytest.mark.parametrize("name,fps", [("humanoid3d_run.txt", 30.0), ("humanoid3d_jog.txt", 30.0),
                                      ("humanoid3d_long_walk3.txt", 120.0)])
def test_other_clips(name, fps):
    clip = load_deepmimic(_need(DM_DIR / name))
    assert clip.fps == fps
    assert 0.7 < clip.root_pos[:, 2].mean() < 1.0
    for knee in ("l_knee", "r_knee"):
        flex = -clip.hinge_angle(knee)
        assert np.all(flex >= -1e-9) and np.all(flex < 2.6)


def test_walk_resample(walk):
    up = walk.resample(2 * walk.fps)
    assert up.n_frames == 2 * walk.n_frames - 1
    assert up.duration == pytest.approx(walk.duration)
    pos, pos_up = walk.global_positions(), up.global_positions()
    np.testing.assert_allclose(pos_up[::2], pos, atol=1e-9)
    # interpolated frames lie between their neighbours (no wild slerp artefacts)
    mid_err = np.linalg.norm(pos_up[1::2] - 0.5 * (pos[:-1] + pos[1:]), axis=-1)
    assert mid_err.max() < 0.02
    # bone lengths are preserved by interpolation (rotations stay rigid)
    sk = walk.skeleton
    j, p = sk.index("l_ankle"), sk.index("l_knee")
    np.testing.assert_allclose(np.linalg.norm(pos_up[:, j] - pos_up[:, p], axis=-1), 0.409870,
                               atol=1e-9)
    down = walk.resample(15.0)
    assert down.n_frames == (walk.n_frames - 1) // 2 + 1
    np.testing.assert_allclose(down.global_positions(), pos[::2], atol=1e-9)


def test_canonical_keypoints_agree_across_formats(walk):
    bvh_path = _need(PACKAGED_MOCAP / "cmu_bvh" / "131_01.bvh")
    cmu = load_bvh(bvh_path)
    kp_dm = canonical_keypoints(walk, require=ALL_KEYPOINTS)
    kp_cmu = canonical_keypoints(cmu, require=ALL_KEYPOINTS)
    assert set(kp_dm) == set(kp_cmu)

    # Legs agree within a few centimetres relative to the hip joints.  (The pelvis
    # itself differs: the CMU root sits ~0.1 m above the hip joints, DeepMimic's at
    # their level; and the CMU BVH torso is shorter, see the report in the bvh module.)
    def rel_height(kp, name):
        hips = 0.5 * (kp["l_hip"][:, 2] + kp["r_hip"][:, 2])
        return float(np.median(kp[name][:, 2] - hips))

    for name in ("l_knee", "r_knee", "l_ankle", "r_ankle", "l_toe", "r_toe"):
        assert abs(rel_height(kp_dm, name) - rel_height(kp_cmu, name)) < 0.15, name
    # the upper body is ordered the same way in both
    for kp in (kp_dm, kp_cmu):
        order = [rel_height(kp, n) for n in ("pelvis", "torso", "neck", "head")]
        assert order == sorted(order)
        assert rel_height(kp, "l_shoulder") > rel_height(kp, "torso")
        assert rel_height(kp, "l_wrist") < rel_height(kp, "l_shoulder")
