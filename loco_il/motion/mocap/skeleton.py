"""Skeletons, motion clips and quaternion helpers for motion-capture data.

Conventions (shared by every loader in :mod:`loco_il.motion.mocap`):

* **World frame: Z up, X forward, Y left** (right-handed), the MuJoCo convention.
  Loaders convert Y-up sources with a proper rotation, so handedness is kept.
  "Forward" is the direction the character faces in its rest pose; the direction
  it walks in the world is whatever the capture recorded.
* **Units: metres, seconds, radians.**
* **Quaternions are w-first** ``(w, x, y, z)``, Hamilton product, active
  rotations: ``v_parent = q * v_child * q^-1``.
* A :class:`Skeleton` lists its joints in topological order (a parent always comes
  before its children; joint 0 is the single root).  ``offsets[j]`` is the rest
  translation of joint ``j`` in its parent's frame.
* ``MotionClip.joint_quats[:, j]`` is the local rotation of joint ``j`` relative to
  its parent's frame (identity for fixed joints and sites).  For the root the
  "parent" is the world, so ``joint_quats[:, 0]`` is kept equal to ``root_quat``.

Forward kinematics, resampling (slerp for rotations, linear for translations),
slicing and scaling are vectorised over frames with numpy.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

__all__ = [
    "JOINT_TYPES",
    "CANONICAL_KEYPOINTS",
    "Skeleton",
    "MotionClip",
    "canonical_keypoints",
    "quat_mul",
    "quat_conj",
    "quat_rotate",
    "quat_normalize",
    "quat_from_axis_angle",
    "quat_from_matrix",
    "quat_to_matrix",
    "quat_slerp",
    "quat_angle",
    "Y_UP_TO_Z_UP",
    "snap_fps",
]

#: Joint kinds.  ``free``: root with 3 translations + 3 rotations; ``ball``: 3
#: rotational degrees of freedom (or 2, for BVH joints with two rotation channels);
#: ``hinge``: one rotation about ``Skeleton.hinge_axes[j]``; ``fixed``: no degree of
#: freedom (end sites, marker points, joints without channels).
JOINT_TYPES = ("free", "ball", "hinge", "fixed")

#: Rotation that maps a Y-up frame whose character faces +X and has its right side
#: at +Z (the DeepMimic convention) to the Z-up, X-forward, Y-left world frame.
#: (BVH files use a different facing convention; see :mod:`.bvh`.)
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def snap_fps(fps: float, rel_tol: float = 1e-4) -> float:
    """Round a frame rate computed from a truncated frame time (``1/0.0083333``) to
    the nearest integer when it is within ``rel_tol`` of it; otherwise unchanged."""
    fps = float(fps)
    r = round(fps)
    if r > 0 and abs(fps - r) <= rel_tol * r:
        return float(r)
    return fps


# ---------------------------------------------------------------------------
# Quaternion helpers (w-first, vectorised over leading dimensions)
# ---------------------------------------------------------------------------
def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of w-first quaternions (broadcasting)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugate (the inverse, for unit quaternions)."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Unit-normalise; zero quaternions become the identity."""
    q = np.asarray(q, dtype=float)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    ident = np.zeros_like(q)
    ident[..., 0] = 1.0
    return np.where(n > 1e-12, q / np.where(n > 1e-12, n, 1.0), ident)


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` (…,3) by unit quaternions ``q`` (…,4)."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def quat_from_axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Quaternion for a rotation of ``angle`` radians about unit ``axis``."""
    axis = np.asarray(axis, dtype=float)
    angle = np.asarray(angle, dtype=float)[..., None]
    half = 0.5 * angle
    return np.concatenate([np.cos(half), np.sin(half) * axis], axis=-1)


def quat_from_matrix(m: np.ndarray) -> np.ndarray:
    """Rotation matrices (…,3,3) to w-first quaternions with ``w >= 0``."""
    from scipy.spatial.transform import Rotation

    m = np.asarray(m, dtype=float)
    shape = m.shape[:-2]
    q = Rotation.from_matrix(m.reshape(-1, 3, 3)).as_quat(scalar_first=True)
    q = np.where(q[:, :1] < 0, -q, q)
    return q.reshape(*shape, 4)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """w-first quaternions (…,4) to rotation matrices (…,3,3)."""
    q = quat_normalize(q)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def quat_slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation along the shorter arc (vectorised).

    ``t`` broadcasts against ``q0[..., 0]``; ``t=0`` gives ``q0``, ``t=1`` gives
    ``q1`` (up to sign).
    """
    q0 = quat_normalize(q0)
    q1 = quat_normalize(q1)
    t = np.asarray(t, dtype=float)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0.0, -q1, q1)
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    theta = np.arccos(dot)
    sin_theta = np.sin(theta)
    small = sin_theta < 1e-6
    safe = np.where(small, 1.0, sin_theta)
    w0 = np.where(small, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    w1 = np.where(small, t, np.sin(t * theta) / safe)
    return quat_normalize(w0 * q0 + w1 * q1)


def quat_angle(q: np.ndarray) -> np.ndarray:
    """Rotation angle in ``[0, pi]`` of unit quaternions."""
    q = quat_normalize(q)
    return 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), np.abs(q[..., 0]))


def _conjugate_by(rot_q: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Express rotation ``q`` in a frame rotated by ``rot_q``: ``r q r^-1``."""
    return quat_mul(quat_mul(rot_q, q), quat_conj(rot_q))


# ---------------------------------------------------------------------------
# Skeleton
# ---------------------------------------------------------------------------
@dataclass
class Skeleton:
    """Kinematic tree of a motion-capture subject.

    Attributes:
        names: standard joint names where the loader knows them (see
            :data:`CANONICAL_KEYPOINTS` and the loaders' name maps), else the source
            names.
        parents: (J,) parent index per joint, ``-1`` for the root (joint 0 only).
        offsets: (J, 3) rest translation of each joint in its parent's frame, metres,
            in the Z-up world convention.
        joint_types: one of :data:`JOINT_TYPES` per joint.
        channels: per joint, the source channels in file order, e.g.
            ``("Zrotation", "Yrotation", "Xrotation")`` for BVH or ``("quat",)`` /
            ``("hinge",)`` for DeepMimic; ``()`` for fixed joints.
        rotation_orders: per joint, the intrinsic Euler order of the source rotation
            channels (e.g. ``"ZYX"``), or ``None`` when the source stores quaternions
            or has no rotation channels.
        hinge_axes: (J, 3) unit rotation axis in the joint's (= parent-aligned rest)
            frame for ``hinge`` joints, zeros otherwise.
        source_names: the joint names as written in the source file.
        is_site: (J,) True for points with no joint in the source (BVH ``End Site``,
            DeepMimic toe/heel/head markers).
    """

    names: list
    parents: np.ndarray
    offsets: np.ndarray
    joint_types: list
    channels: list = None  # type: ignore[assignment]
    rotation_orders: list = None  # type: ignore[assignment]
    hinge_axes: np.ndarray = None  # type: ignore[assignment]
    source_names: list = None  # type: ignore[assignment]
    is_site: np.ndarray = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        self.names = [str(n) for n in self.names]
        j = len(self.names)
        self.parents = np.asarray(self.parents, dtype=np.int64).reshape(-1)
        self.offsets = np.asarray(self.offsets, dtype=float).reshape(-1, 3)
        self.joint_types = list(self.joint_types)
        if self.channels is None:
            self.channels = [()] * j
        self.channels = [tuple(c) for c in self.channels]
        if self.rotation_orders is None:
            self.rotation_orders = [None] * j
        self.rotation_orders = list(self.rotation_orders)
        if self.hinge_axes is None:
            self.hinge_axes = np.zeros((j, 3))
        self.hinge_axes = np.asarray(self.hinge_axes, dtype=float).reshape(-1, 3)
        if self.source_names is None:
            self.source_names = list(self.names)
        self.source_names = [str(n) for n in self.source_names]
        if self.is_site is None:
            self.is_site = np.zeros(j, dtype=bool)
        self.is_site = np.asarray(self.is_site, dtype=bool).reshape(-1)

        for attr in ("parents", "offsets", "joint_types", "channels", "rotation_orders",
                     "hinge_axes", "source_names", "is_site"):
            if len(getattr(self, attr)) != j:
                raise ValueError(f"Skeleton.{attr} has {len(getattr(self, attr))} entries, expected {j}")
        if j == 0:
            raise ValueError("Skeleton needs at least one joint")
        if self.parents[0] != -1:
            raise ValueError("joint 0 must be the root (parent -1)")
        for i in range(1, j):
            if not 0 <= self.parents[i] < i:
                raise ValueError(
                    f"joint {i} ({self.names[i]!r}) has parent {self.parents[i]}: joints must be in "
                    "topological order with a single root at index 0")
        bad = [t for t in self.joint_types if t not in JOINT_TYPES]
        if bad:
            raise ValueError(f"unknown joint types {bad}; expected one of {JOINT_TYPES}")
        if len(set(self.names)) != j:
            dup = sorted({n for n in self.names if self.names.count(n) > 1})
            raise ValueError(f"duplicate joint names {dup}")

    # -- queries ----------------------------------------------------------
    @property
    def n_joints(self) -> int:
        """Number of joints, sites included."""
        return len(self.names)

    @property
    def n_source_joints(self) -> int:
        """Number of joints that exist in the source file (sites excluded)."""
        return int((~self.is_site).sum())

    def index(self, name: str) -> int:
        """Index of a joint by standard or source name."""
        if name in self.names:
            return self.names.index(name)
        if name in self.source_names:
            return self.source_names.index(name)
        raise KeyError(f"no joint named {name!r}; joints: {self.names}")

    def __contains__(self, name: str) -> bool:
        return name in self.names or name in self.source_names

    def children(self, j: int) -> list:
        return [i for i in range(self.n_joints) if self.parents[i] == j]

    def scaled(self, factor: float) -> "Skeleton":
        return dataclasses.replace(self, offsets=self.offsets * float(factor))

    def rest_positions(self) -> np.ndarray:
        """(J, 3) global joint positions in the rest pose with the root at the origin."""
        pos = np.zeros((self.n_joints, 3))
        for j in range(1, self.n_joints):
            pos[j] = pos[self.parents[j]] + self.offsets[j]
        return pos

    def rest_height(self) -> float:
        """Vertical extent (z) of the rest pose, metres."""
        z = self.rest_positions()[:, 2]
        return float(z.max() - z.min())


# ---------------------------------------------------------------------------
# MotionClip
# ---------------------------------------------------------------------------
@dataclass
class MotionClip:
    """A motion: per-frame root pose and local joint rotations on a :class:`Skeleton`.

    Attributes:
        skeleton: the kinematic tree.
        fps: frames per second.
        root_pos: (T, 3) root joint position, metres, Z-up world.
        root_quat: (T, 4) root orientation, w-first.
        joint_quats: (T, J, 4) local joint rotations, w-first (identity for fixed
            joints; ``[:, 0]`` equals ``root_quat``).
        joint_translations: optional (T, J, 3) per-frame local translations replacing
            ``skeleton.offsets`` (BVH position channels on non-root joints); ``None``
            when every joint uses its rest offset.
        loop: whether the source marks the clip as cyclic.
        name: a short label (file stem by default).
        meta: free-form provenance (source path, format, unit scale, ...).
    """

    skeleton: Skeleton
    fps: float
    root_pos: np.ndarray
    root_quat: np.ndarray
    joint_quats: np.ndarray
    joint_translations: Optional[np.ndarray] = None
    loop: bool = False
    name: str = ""
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.fps = float(self.fps)
        if not np.isfinite(self.fps) or self.fps <= 0:
            raise ValueError(f"fps must be positive, got {self.fps}")
        self.root_pos = np.asarray(self.root_pos, dtype=float).reshape(-1, 3)
        t = self.root_pos.shape[0]
        self.root_quat = quat_normalize(np.asarray(self.root_quat, dtype=float).reshape(t, 4))
        j = self.skeleton.n_joints
        jq = np.asarray(self.joint_quats, dtype=float)
        if jq.shape != (t, j, 4):
            raise ValueError(f"joint_quats has shape {jq.shape}, expected {(t, j, 4)}")
        jq = quat_normalize(jq)
        jq[:, 0] = self.root_quat
        self.joint_quats = jq
        if self.joint_translations is not None:
            tr = np.asarray(self.joint_translations, dtype=float)
            if tr.shape != (t, j, 3):
                raise ValueError(f"joint_translations has shape {tr.shape}, expected {(t, j, 3)}")
            self.joint_translations = tr
        if t == 0:
            raise ValueError("a MotionClip needs at least one frame")

    # -- basic properties ---------------------------------------------------
    @property
    def n_frames(self) -> int:
        return int(self.root_pos.shape[0])

    def __len__(self) -> int:
        return self.n_frames

    @property
    def dt(self) -> float:
        return 1.0 / self.fps

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame: ``(n_frames - 1) / fps``."""
        return (self.n_frames - 1) / self.fps

    @property
    def times(self) -> np.ndarray:
        """(T,) time stamp of each frame, seconds from the first."""
        return np.arange(self.n_frames) / self.fps

    @property
    def joint_names(self) -> list:
        return list(self.skeleton.names)

    def replace(self, **changes) -> "MotionClip":
        """A copy with some fields replaced (``dataclasses.replace``)."""
        return dataclasses.replace(self, **changes)

    # -- kinematics -----------------------------------------------------------
    def global_transforms(self) -> tuple:
        """Forward kinematics: ``(positions (T,J,3), quats (T,J,4))`` in the world."""
        sk = self.skeleton
        t, j = self.n_frames, sk.n_joints
        pos = np.empty((t, j, 3))
        rot = np.empty((t, j, 4))
        pos[:, 0] = self.root_pos
        rot[:, 0] = self.root_quat
        tr = self.joint_translations
        for i in range(1, j):
            p = sk.parents[i]
            off = sk.offsets[i] if tr is None else tr[:, i]
            pos[:, i] = pos[:, p] + quat_rotate(rot[:, p], off)
            rot[:, i] = quat_mul(rot[:, p], self.joint_quats[:, i])
        return pos, rot

    def global_positions(self) -> np.ndarray:
        """(T, J, 3) world positions of every joint (sites included), metres."""
        return self.global_transforms()[0]

    def joint_position(self, name: str) -> np.ndarray:
        """(T, 3) world position of one joint."""
        return self.global_positions()[:, self.skeleton.index(name)]

    def hinge_angle(self, name: str) -> np.ndarray:
        """(T,) signed angle (radians) of a hinge joint about its ``hinge_axes`` axis."""
        j = self.skeleton.index(name)
        if self.skeleton.joint_types[j] != "hinge":
            raise ValueError(f"joint {name!r} is a {self.skeleton.joint_types[j]} joint, not a hinge")
        q = self.joint_quats[:, j]
        s = q[:, 1:] @ self.skeleton.hinge_axes[j]
        ang = 2.0 * np.arctan2(s, q[:, 0])
        return (ang + np.pi) % (2 * np.pi) - np.pi

    # -- editing --------------------------------------------------------------
    def _sample(self, frame_idx: np.ndarray) -> dict:
        """Interpolate all per-frame arrays at fractional frame indices."""
        frame_idx = np.asarray(frame_idx, dtype=float)
        t = self.n_frames
        if t == 1:
            i0 = np.zeros(frame_idx.shape, dtype=np.int64)
            i1 = i0
            f = np.zeros(frame_idx.shape)
        else:
            s = np.clip(frame_idx, 0.0, t - 1)
            i0 = np.minimum(np.floor(s).astype(np.int64), t - 2)
            i1 = i0 + 1
            f = s - i0
        out = {
            "root_pos": self.root_pos[i0] * (1 - f)[:, None] + self.root_pos[i1] * f[:, None],
            "root_quat": quat_slerp(self.root_quat[i0], self.root_quat[i1], f),
            "joint_quats": quat_slerp(self.joint_quats[i0], self.joint_quats[i1], f[:, None]),
        }
        if self.joint_translations is not None:
            ff = f[:, None, None]
            out["joint_translations"] = (self.joint_translations[i0] * (1 - ff)
                                         + self.joint_translations[i1] * ff)
        return out

    def resample(self, new_fps: float) -> "MotionClip":
        """Resample to ``new_fps`` (slerp for rotations, linear for translations).

        The new frames sit at ``k / new_fps`` for every ``k`` that stays within
        ``duration``, so the first frame is kept and times common to both rates give
        the same pose.
        """
        new_fps = float(new_fps)
        if not np.isfinite(new_fps) or new_fps <= 0:
            raise ValueError(f"new_fps must be positive, got {new_fps}")
        n_new = int(np.floor(self.duration * new_fps + 1e-6)) + 1
        idx = np.arange(n_new) * (self.fps / new_fps)
        meta = dict(self.meta, resampled_from_fps=self.fps)
        return self.replace(fps=new_fps, meta=meta, **self._sample(idx))

    def resample_times(self, times: Sequence[float], fps: float) -> "MotionClip":
        """Sample the clip at arbitrary times (seconds) and label the result ``fps``."""
        idx = np.asarray(times, dtype=float) * self.fps
        return self.replace(fps=float(fps), **self._sample(idx))

    def slice(self, start: Optional[int] = None, stop: Optional[int] = None) -> "MotionClip":
        """Frames ``[start:stop]`` (Python slice semantics, step 1)."""
        sl = slice(start, stop)
        idx = np.arange(self.n_frames)[sl]
        if idx.size == 0:
            raise ValueError(f"slice({start}, {stop}) of a {self.n_frames}-frame clip is empty")
        kw = dict(root_pos=self.root_pos[sl].copy(), root_quat=self.root_quat[sl].copy(),
                  joint_quats=self.joint_quats[sl].copy(), loop=False)
        if self.joint_translations is not None:
            kw["joint_translations"] = self.joint_translations[sl].copy()
        return self.replace(**kw)

    def scale(self, factor: float) -> "MotionClip":
        """Scale all lengths (skeleton offsets, root trajectory, translations)."""
        factor = float(factor)
        if not np.isfinite(factor) or factor <= 0:
            raise ValueError(f"scale factor must be positive, got {factor}")
        kw = dict(skeleton=self.skeleton.scaled(factor), root_pos=self.root_pos * factor)
        if self.joint_translations is not None:
            kw["joint_translations"] = self.joint_translations * factor
        return self.replace(**kw)

    def grounded(self, height: float = 0.0) -> "MotionClip":
        """Shift vertically so the lowest joint over the whole clip sits at ``height``."""
        lowest = float(self.global_positions()[..., 2].min())
        root_pos = self.root_pos.copy()
        root_pos[:, 2] += height - lowest
        return self.replace(root_pos=root_pos)

    def rotated_to_world(self, rot_q: np.ndarray) -> "MotionClip":
        """Apply a fixed world-frame change of basis ``rot_q`` to the whole clip.

        Both the skeleton (offsets, hinge axes) and every rotation are conjugated,
        so :meth:`global_positions` of the result equals ``rot_q`` applied to the
        original positions.
        """
        rot_q = quat_normalize(np.asarray(rot_q, dtype=float))
        sk = self.skeleton
        new_sk = dataclasses.replace(sk, offsets=quat_rotate(rot_q, sk.offsets),
                                     hinge_axes=quat_rotate(rot_q, sk.hinge_axes))
        kw = dict(skeleton=new_sk, root_pos=quat_rotate(rot_q, self.root_pos),
                  root_quat=_conjugate_by(rot_q, self.root_quat),
                  joint_quats=_conjugate_by(rot_q, self.joint_quats))
        if self.joint_translations is not None:
            kw["joint_translations"] = quat_rotate(rot_q, self.joint_translations)
        return self.replace(**kw)


# ---------------------------------------------------------------------------
# Canonical keypoints
# ---------------------------------------------------------------------------
#: Keypoints shared by every supported skeleton, for retargeting.  Each maps to a
#: list of standard joint names tried in order.  Semantics:
#: ``pelvis`` the source's root joint (DeepMimic: at hip-joint height; CMU BVH:
#: ~0.1 m above the hip joints); ``l_/r_hip`` hip (femur-head) joint; ``l_/r_knee``;
#: ``l_/r_ankle``; ``l_/r_toe`` front of the foot (ball of the foot / toe joint);
#: ``torso`` upper-trunk spine joint about 0.22 m above the pelvis; ``neck`` base of
#: the neck; ``head`` roughly the centre of the head; ``l_/r_shoulder`` gleno-humeral
#: joint; ``l_/r_elbow``; ``l_/r_wrist``.
CANONICAL_KEYPOINTS = {
    "pelvis": ["pelvis"],
    "l_hip": ["l_hip"],
    "r_hip": ["r_hip"],
    "l_knee": ["l_knee"],
    "r_knee": ["r_knee"],
    "l_ankle": ["l_ankle"],
    "r_ankle": ["r_ankle"],
    "l_toe": ["l_toe"],
    "r_toe": ["r_toe"],
    "torso": ["chest", "spine1", "spine"],
    "neck": ["neck", "lower_neck"],
    "head": ["head"],
    "l_shoulder": ["l_shoulder"],
    "r_shoulder": ["r_shoulder"],
    "l_elbow": ["l_elbow"],
    "r_elbow": ["r_elbow"],
    "l_wrist": ["l_wrist", "l_hand"],
    "r_wrist": ["r_wrist", "r_hand"],
}


def canonical_keypoints(clip: MotionClip, require: Optional[Sequence[str]] = None) -> dict:
    """World positions of the canonical keypoints of ``clip``.

    Returns ``{keypoint: (T, 3) array}`` for every name in
    :data:`CANONICAL_KEYPOINTS` that the skeleton provides (loaders give joints
    standard names, so this works for BVH and DeepMimic clips alike).  Names in
    ``require`` that cannot be found raise ``KeyError``.
    """
    pos = clip.global_positions()
    names = clip.skeleton.names
    out = {}
    for key, candidates in CANONICAL_KEYPOINTS.items():
        for cand in candidates:
            if cand in names:
                out[key] = pos[:, names.index(cand)]
                break
    missing = [k for k in (require or ()) if k not in out]
    if missing:
        raise KeyError(f"keypoints {missing} not available for skeleton with joints {names}")
    return out
