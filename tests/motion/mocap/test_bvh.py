"""Tests for the BVH loader and the MotionClip helpers (FK, resample, slice, scale)."""

from pathlib import Path

import numpy as np
import pytest

from loco_il.motion.mocap import BVHParseError, canonical_keypoints, load_bvh
from loco_il.motion.mocap.bvh import CMU_BVH_NAME_MAP, UNIT_SCALES, detect_unit_scale

from loco_il.motion.mocap.clips import PACKAGED_MOCAP  # noqa: E402  (the clips shipped in the package)
CMU_DIR = PACKAGED_MOCAP / "cmu_bvh"


def _need_cmu(name: str) -> Path:
    path = CMU_DIR / name
    assert path.is_file(), f"{path} is missing from the package data"
    return path


# A 3-joint leg in centimetres: Hips -> Knee -> Ankle -> End Site (toe, 5 cm forward).
LEG_BVH = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Knee
  {
    OFFSET 0 -10 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    JOINT Ankle
    {
      OFFSET 0 -10 0
      CHANNELS 3 Zrotation Yrotation Xrotation
      End Site
      {
        OFFSET 0 0 5
      }
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.04
0 100 0 0 0 0 0 0 0 0 0 0
0 100 0 0 0 0 0 0 90 0 0 0
10 100 0 0 0 0 0 0 0 0 0 0
"""


def _write(tmp_path, text, name="clip.bvh"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _bvh_to_world(v):
    """BVH (x left, y up, z forward) -> world (x forward, y left, z up)."""
    v = np.asarray(v, dtype=float)
    return np.array([v[2], v[0], v[1]])


def _rx(deg):
    a = np.radians(deg)
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def _ry(deg):
    a = np.radians(deg)
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def _rz(deg):
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


# ---------------------------------------------------------------------------
# Synthetic files (no shared data needed)
# ---------------------------------------------------------------------------
def test_counts_and_frame_rate(tmp_path):
    clip = load_bvh(_write(tmp_path, LEG_BVH), scale=0.01)
    sk = clip.skeleton
    assert sk.n_source_joints == 3
    assert sk.n_joints == 4  # + the End Site
    assert sk.source_names == ["Hips", "Knee", "Ankle", "Ankle_End"]
    assert list(sk.parents) == [-1, 0, 1, 2]
    assert sk.joint_types == ["free", "ball", "ball", "fixed"]
    assert sk.rotation_orders[:3] == ["ZYX", "ZYX", "ZYX"]
    assert sk.is_site.tolist() == [False, False, False, True]
    assert clip.n_frames == 3
    assert clip.fps == pytest.approx(25.0)
    assert clip.duration == pytest.approx(2 / 25.0)
    assert clip.joint_quats.shape == (3, 4, 4)
    np.testing.assert_allclose(clip.joint_quats[:, 3], [[1, 0, 0, 0]] * 3)  # fixed site: identity


def test_known_pose_forward_kinematics(tmp_path):
    clip = load_bvh(_write(tmp_path, LEG_BVH), scale=0.01)
    pos = clip.global_positions()
    assert pos.shape == (3, 4, 3)
    # frame 0: rest pose, hips 1 m up
    np.testing.assert_allclose(pos[0, 0], _bvh_to_world([0, 1.0, 0]), atol=1e-12)
    np.testing.assert_allclose(pos[0, 2], [0, 0, 0.8], atol=1e-12)
    np.testing.assert_allclose(pos[0, 3], [0.05, 0, 0.8], atol=1e-12)  # toe points forward (+x)
    # frame 1: knee rotated 90 deg about the BVH X (= world Y, left) axis: the shank
    # swings backwards to horizontal and the toe then points down.
    np.testing.assert_allclose(pos[1, 1], [0, 0, 0.9], atol=1e-12)
    np.testing.assert_allclose(pos[1, 2], [-0.1, 0, 0.9], atol=1e-12)
    np.testing.assert_allclose(pos[1, 3], [-0.1, 0, 0.85], atol=1e-12)
    # frame 2: root translated along BVH +X = world +Y (left)
    np.testing.assert_allclose(pos[2, 0], [0, 0.1, 1.0], atol=1e-12)
    np.testing.assert_allclose(pos[2, 3], [0.05, 0.1, 0.8], atol=1e-12)


@pytest.mark.parametrize("order", ["XYZ", "ZYX", "ZXY", "YXZ"])
def test_euler_order(tmp_path, order):
    # angles per axis; the values are written in the channel order
    angles = {"X": 90.0, "Y": 30.0, "Z": 90.0}
    chans = " ".join(f"{a}rotation" for a in order)
    vals = " ".join(str(angles[a]) for a in order)
    text = f"""HIERARCHY
ROOT Root
{{
  OFFSET 0 0 0
  CHANNELS 3 Xposition Yposition Zposition
  JOINT Arm
  {{
    OFFSET 0 0 0
    CHANNELS 3 {chans}
    End Site
    {{
      OFFSET 0 1 0
    }}
  }}
}}
MOTION
Frames: 1
Frame Time: 0.01
0 0 0 {vals}
"""
    clip = load_bvh(_write(tmp_path, text), scale=1.0)
    mats = {"X": _rx, "Y": _ry, "Z": _rz}
    R = np.eye(3)
    for a in order:  # intrinsic: R = R_first @ R_second @ R_third
        R = R @ mats[a](angles[a])
    expected = _bvh_to_world(R @ np.array([0.0, 1.0, 0.0]))
    got = clip.global_positions()[0, 2]
    np.testing.assert_allclose(got, expected, atol=1e-9)
    assert clip.skeleton.rotation_orders[1] == order


def test_euler_orders_differ(tmp_path):
    def end_pos(order):
        chans = " ".join(f"{a}rotation" for a in order)
        vals = " ".join({"X": "90", "Y": "0", "Z": "90"}[a] for a in order)
        text = LEG_BVH.split("MOTION")[0].replace(
            "CHANNELS 3 Zrotation Yrotation Xrotation\n    JOINT Ankle",
            f"CHANNELS 3 {chans}\n    JOINT Ankle")
        text += f"MOTION\nFrames: 1\nFrame Time: 0.01\n0 100 0 0 0 0 {vals} 0 0 0\n"
        return load_bvh(_write(tmp_path, text, f"{order}.bvh"), scale=0.01).global_positions()[0]

    xyz, zyx = end_pos("XYZ"), end_pos("ZYX")
    # XYZ: Rx(90) Rz(90) (0,-10,0) = (10, 0, 0) -> ankle at knee + 10 cm along BVH +X (world +Y)
    np.testing.assert_allclose(xyz[2], [0, 0.1, 0.9], atol=1e-12)
    # ZYX: Rz(90) Rx(90) (0,-10,0) = (0, 0, -10) -> 10 cm along BVH -Z (world -X)
    np.testing.assert_allclose(zyx[2], [-0.1, 0, 0.9], atol=1e-12)


def test_position_channels_on_child_joint(tmp_path):
    text = LEG_BVH.replace(
        "    OFFSET 0 -10 0\n    CHANNELS 3 Zrotation Yrotation Xrotation\n    JOINT Ankle",
        "    OFFSET 0 -10 0\n    CHANNELS 4 Yposition Zrotation Yrotation Xrotation\n    JOINT Ankle")
    text = text.split("MOTION")[0] + "MOTION\nFrames: 2\nFrame Time: 0.04\n" \
        "0 100 0 0 0 0 -10 0 0 0 0 0 0\n0 100 0 0 0 0 -20 0 0 0 0 0 0\n"
    clip = load_bvh(_write(tmp_path, text), scale=0.01)
    assert clip.joint_translations is not None
    knee = clip.global_positions()[:, 1]
    np.testing.assert_allclose(knee[:, 2], [0.9, 0.8], atol=1e-12)  # Yposition replaces OFFSET y


def test_unit_detection(tmp_path):
    # the leg above spans 20 file units: detection picks the CMU unit (20 * 0.0564 = 1.13 m)
    clip = load_bvh(_write(tmp_path, LEG_BVH))
    assert clip.meta["unit"] == "cmu"
    assert clip.meta["scale"] == pytest.approx(0.0254 / 0.45)
    assert detect_unit_scale(170.0)[0] == "cm"
    assert detect_unit_scale(1650.0)[0] == "mm"
    assert detect_unit_scale(1.6)[0] == "m"
    assert detect_unit_scale(62.0)[0] == "in"
    assert detect_unit_scale(26.0)[0] == "cmu"
    assert UNIT_SCALES["cmu"] == pytest.approx(0.056444, rel=1e-4)
    # an explicit scale wins
    clip = load_bvh(_write(tmp_path, LEG_BVH), scale=0.02)
    np.testing.assert_allclose(clip.root_pos[0], [0, 0, 2.0])


@pytest.mark.parametrize(
    "old,new,line,msg",
    [
        ("OFFSET 0 -10 0\n    CHANNELS 3 Zrotation", "OFFSET 0 -1x 0\n    CHANNELS 3 Zrotation", 8, "number"),
        ("CHANNELS 3 Zrotation Yrotation Xrotation\n    JOINT Ankle",
         "CHANNELS 3 Zrotation Yrotation Wrotation\n    JOINT Ankle", 9, "unknown channel"),
        ("10 100 0 0 0 0 0 0 0 0 0 0", "10 100 0 0 0 0 0 0 0 0 0", 26, "11 values"),
        ("0 100 0 0 0 0 0 0 90 0 0 0", "0 100 0 0 0 0 0 0 abc 0 0 0", 25, "'abc'"),
        ("Frames: 3", "Frames: 4", 26, "declares 4 frames"),
        ("Frames: 3", "Frames: 2", 26, "more frame lines"),
        ("Frame Time: 0.04", "Frame Tme: 0.04", 23, "Frame Time"),
        ("      OFFSET 0 0 5\n", "      OFSET 0 0 5\n", 16, "OFSET"),
    ],
)
def test_malformed_files_report_line(tmp_path, old, new, line, msg):
    assert old in LEG_BVH
    path = _write(tmp_path, LEG_BVH.replace(old, new, 1))
    with pytest.raises(BVHParseError) as err:
        load_bvh(path)
    assert f"{path}:{line}:" in str(err.value)
    assert msg in str(err.value)


def test_truncated_hierarchy(tmp_path):
    text = LEG_BVH.split("MOTION")[0].rsplit("}", 2)[0] + "MOTION\nFrames: 1\nFrame Time: 0.1\n"
    with pytest.raises(BVHParseError, match="end of HIERARCHY"):
        load_bvh(_write(tmp_path, text))
    with pytest.raises(BVHParseError, match="HIERARCHY"):
        load_bvh(_write(tmp_path, "hello\n"))


def test_resample_slice_scale(tmp_path):
    clip = load_bvh(_write(tmp_path, LEG_BVH), scale=0.01)
    up = clip.resample(2 * clip.fps)
    assert up.n_frames == 2 * clip.n_frames - 1
    assert up.fps == pytest.approx(50.0)
    assert up.duration == pytest.approx(clip.duration)
    pos, pos_up = clip.global_positions(), up.global_positions()
    np.testing.assert_allclose(pos_up[::2], pos, atol=1e-12)  # shared times keep their pose
    # halfway between frames 0 and 1 the knee is at 45 degrees (slerp, not lerp):
    # the ankle lies on the circle of radius 0.1 around the knee
    mid = pos_up[1]
    np.testing.assert_allclose(mid[2], [-0.1 * np.sin(np.pi / 4), 0, 0.9 - 0.1 * np.cos(np.pi / 4)],
                               atol=1e-12)
    # a quarter of the way the knee is at 22.5 degrees (constant angular speed)
    quarter = clip.resample(4 * clip.fps).global_positions()[1]
    a = np.pi / 8
    np.testing.assert_allclose(quarter[2], [-0.1 * np.sin(a), 0, 0.9 - 0.1 * np.cos(a)], atol=1e-12)
    # root translation is linear
    np.testing.assert_allclose(pos_up[3, 0], [0, 0.05, 1.0], atol=1e-12)
    down = up.resample(25.0)
    np.testing.assert_allclose(down.global_positions(), pos, atol=1e-12)

    part = clip.slice(1, 3)
    assert part.n_frames == 2
    np.testing.assert_allclose(part.global_positions(), pos[1:3])
    with pytest.raises(ValueError):
        clip.slice(5, 6)

    big = clip.scale(2.0)
    np.testing.assert_allclose(big.global_positions(), 2.0 * pos, atol=1e-12)
    low = clip.grounded()
    assert low.global_positions()[..., 2].min() == pytest.approx(0.0, abs=1e-12)


def test_name_map_applied(tmp_path):
    text = (LEG_BVH.replace("ROOT Hips", "ROOT Hips").replace("JOINT Knee", "JOINT LeftKnee")
            .replace("JOINT Ankle", "JOINT LeftAnkle"))
    clip = load_bvh(_write(tmp_path, text), scale=0.01)
    assert clip.skeleton.names == ["pelvis", "l_knee", "l_ankle", "l_ankle_end"]
    assert clip.meta["name_map"] == "cmu"
    kp = canonical_keypoints(clip)
    assert set(kp) == {"pelvis", "l_knee", "l_ankle"}
    clip_raw = load_bvh(_write(tmp_path, text, "b.bvh"), scale=0.01, name_map=False)
    assert clip_raw.skeleton.names[:3] == ["Hips", "LeftKnee", "LeftAnkle"]
    with pytest.raises(KeyError):
        canonical_keypoints(clip, require=["head"])


# ---------------------------------------------------------------------------
# Real CMU files from the package data (loco_il/motion/mocap/data)
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def cmu_walk():
    return load_bvh(_need_cmu("131_02.bvh"))


def test_cmu_structure(cmu_walk):
    path = _need_cmu("131_02.bvh")
    text = path.read_text()
    n_joints = sum(1 for ln in text.splitlines() if ln.split()[:1] in (["ROOT"], ["JOINT"]))
    n_sites = text.count("End Site")
    n_chan = sum(int(ln.split()[1]) for ln in text.splitlines() if ln.strip().startswith("CHANNELS"))
    sk = cmu_walk.skeleton
    assert sk.n_source_joints == n_joints == 31
    assert sk.n_joints == n_joints + n_sites
    assert n_chan == 96
    declared = int(next(ln for ln in text.splitlines() if ln.startswith("Frames:")).split()[1])
    assert cmu_walk.n_frames == declared == 1247
    assert cmu_walk.fps == 120.0
    assert cmu_walk.meta["unit"] == "cmu"
    assert set(CMU_BVH_NAME_MAP.values()) <= set(sk.names)


def test_cmu_metric_size_and_ground(cmu_walk):
    sk = cmu_walk.skeleton
    # Joint-span height (toe to head end site).  CMU end sites stop short of the crown,
    # so this is below stature (see loco_il.motion.mocap.bvh).
    assert 1.2 < sk.rest_height() < 2.0
    pos = cmu_walk.global_positions()
    kp = canonical_keypoints(cmu_walk)
    standing = pos[0, sk.index("head_end"), 2] - min(kp["l_toe"][0, 2], kp["r_toe"][0, 2])
    assert 1.2 < standing < 2.0
    assert 0.85 < cmu_walk.root_pos[0, 2] < 1.05  # pelvis height of an adult
    thigh = np.linalg.norm(kp["l_knee"][0] - kp["l_hip"][0])
    shank = np.linalg.norm(kp["l_ankle"][0] - kp["l_knee"][0])
    assert 0.35 < thigh < 0.5 and 0.33 < shank < 0.48
    # feet are near the floor (no grounding applied: the capture's floor is z = 0)
    lowest = pos[..., 2].min(axis=1)
    assert abs(np.median(lowest)) < 0.1
    assert lowest.min() > -0.1
    # head above pelvis above feet: Z is up
    assert np.all(kp["head"][:, 2] > kp["pelvis"][:, 2])
    assert np.all(kp["pelvis"][:, 2] > np.maximum(kp["l_ankle"][:, 2], kp["r_ankle"][:, 2]))


@pytest.mark.parametrize("name", ["131_01.bvh", "131_02.bvh"])
def test_cmu_walk_moves_forward(name):
    clip = load_bvh(_need_cmu(name))
    kp = canonical_keypoints(clip)
    left = kp["l_hip"][0] - kp["r_hip"][0]
    forward = np.cross(left, [0.0, 0.0, 1.0])  # x forward, y left, z up
    forward /= np.linalg.norm(forward)
    disp = clip.root_pos[-1] - clip.root_pos[0]
    assert disp @ forward > 1.0
    # toes point forward too (the rest-pose facing is +X in the clip's skeleton)
    toe_dir = kp["l_toe"][0] - kp["l_ankle"][0]
    assert toe_dir @ forward > 0


def test_cmu_canonical_keypoints(cmu_walk):
    kp = canonical_keypoints(cmu_walk, require=[
        "pelvis", "l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle", "l_toe", "r_toe",
        "torso", "neck", "head", "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist",
        "r_wrist"])
    assert all(v.shape == (cmu_walk.n_frames, 3) for v in kp.values())
    # left is +Y in the body frame: the left hip is on the left of the right hip
    left = kp["l_hip"] - kp["r_hip"]
    assert np.linalg.norm(left[0]) > 0.1


def test_cmu_resample(cmu_walk):
    part = cmu_walk.slice(0, 241)
    down = part.resample(30.0)
    assert down.n_frames == 61
    np.testing.assert_allclose(down.global_positions(), part.global_positions()[::4], atol=1e-9)
