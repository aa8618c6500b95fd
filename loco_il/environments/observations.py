"""Named observation layout: which entry of the observation vector means what.

Observation = joint positions (without the root's horizontal world coordinates), then joint
velocities, then task features (e.g. a commanded direction). Each entry has a name and a group;
POMDP variants hide whole groups with a boolean mask.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import mujoco
import numpy as np

_FREE_POS = ("x", "y", "z", "qw", "qx", "qy", "qz")
_FREE_VEL = ("vx", "vy", "vz", "wx", "wy", "wz")
_BALL_POS = ("qw", "qx", "qy", "qz")
_BALL_VEL = ("wx", "wy", "wz")


@dataclass(frozen=True)
class ObservationSpec:
    """Names and groups of the observation entries; `slices[name]` indexes the observation vector."""

    names: tuple[str, ...]
    groups: tuple[str, ...]

    @property
    def dim(self) -> int:
        return len(self.names)

    @property
    def slices(self) -> dict[str, slice]:
        return {n: slice(i, i + 1) for i, n in enumerate(self.names)}

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no observation entry named {name!r}; entries: {', '.join(self.names)}") from None

    def mask(self, hide_groups: Sequence[str] = (), hide_names: Sequence[str] = ()) -> np.ndarray:
        """Boolean mask, True = visible. Unknown group or entry names raise, so typos cannot silently hide nothing."""
        known = set(self.groups)
        for g in hide_groups:
            if g not in known:
                raise KeyError(f"unknown observation group {g!r}; groups here: {sorted(known)}")
        for n in hide_names:
            self.index(n)
        return np.array([g not in hide_groups and n not in hide_names for n, g in zip(self.names, self.groups)])

    def masked(self, mask: np.ndarray) -> "ObservationSpec":
        return ObservationSpec(tuple(n for n, m in zip(self.names, mask) if m),
                               tuple(g for g, m in zip(self.groups, mask) if m))


@dataclass(frozen=True)
class JointLayout:
    """qpos/qvel indices that form the observation (computed once per compiled model)."""

    qpos_idx: np.ndarray
    qvel_idx: np.ndarray
    pos_names: tuple[str, ...]
    vel_names: tuple[str, ...]


def root_joint_world_axis(model: mujoco.MjModel, joint: int) -> np.ndarray:
    """A root joint's axis in world coordinates (`jnt_axis` is in the body frame, which may be rotated:
    LocoMuJoCo's humanoid pelvis is turned 90 degrees about x, making `pelvis_ty` its vertical slide)."""
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, model.body_quat[model.jnt_bodyid[joint]])
    return rot.reshape(3, 3) @ model.jnt_axis[joint]


def horizontal_root_qpos(model: mujoco.MjModel) -> set[int]:
    """qpos addresses of the root's horizontal world coordinates (excluded from observations).

    A free joint's x and y, or a slide joint on a root-level body whose axis is horizontal
    (Hopper's rootx, LocoMuJoCo's pelvis_tx/pelvis_tz).
    """
    excluded: set[int] = set()
    for j in range(model.njnt):
        body = model.jnt_bodyid[j]
        if model.body_parentid[body] != 0:
            continue
        adr = model.jnt_qposadr[j]
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            excluded.update((adr, adr + 1))
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
            if abs(root_joint_world_axis(model, j)[2]) < 1e-6:
                excluded.add(adr)
    return excluded


def root_xy_projection(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """(qpos indices, 2xk matrix) such that `P @ qpos[idx]` is the root's horizontal world position.

    Gymnasium measures Hopper/Walker/HalfCheetah progress on the root slide joint (qpos[0]) and
    LocoMuJoCo on pelvis_tx; a free joint's x, y are the root body's position. Empty if the root
    has no horizontal degrees of freedom (the env then falls back to the root body's position).
    """
    idx, cols = [], []
    for j in range(model.njnt):
        if model.body_parentid[model.jnt_bodyid[j]] != 0:
            continue
        adr = model.jnt_qposadr[j]
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            idx += [adr, adr + 1]
            cols += [(1.0, 0.0), (0.0, 1.0)]
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
            axis = root_joint_world_axis(model, j)
            if abs(axis[2]) < 1e-6:
                idx.append(adr)
                cols.append(tuple(axis[:2]))
    return np.array(idx, dtype=np.intp), np.array(cols, dtype=np.float64).reshape(-1, 2).T


def joint_layout(model: mujoco.MjModel, exclude_root_xy: bool = True) -> JointLayout:
    excluded = horizontal_root_qpos(model) if exclude_root_xy else set()
    qpos_idx, qvel_idx, pos_names, vel_names = [], [], [], []
    for j in range(model.njnt):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
        jtype = model.jnt_type[j]
        padr, vadr = model.jnt_qposadr[j], model.jnt_dofadr[j]
        if jtype == mujoco.mjtJoint.mjJNT_FREE:
            psuf, vsuf = _FREE_POS, _FREE_VEL
        elif jtype == mujoco.mjtJoint.mjJNT_BALL:
            psuf, vsuf = _BALL_POS, _BALL_VEL
        else:
            psuf, vsuf = ("",), ("",)
        for k, s in enumerate(psuf):
            if padr + k not in excluded:
                qpos_idx.append(padr + k)
                pos_names.append(f"q_{name}" + (f"_{s}" if s else ""))
        for k, s in enumerate(vsuf):
            qvel_idx.append(vadr + k)
            vel_names.append(f"dq_{name}" + (f"_{s}" if s else ""))
    return JointLayout(np.array(qpos_idx, dtype=np.intp), np.array(qvel_idx, dtype=np.intp),
                       tuple(pos_names), tuple(vel_names))


def observation_spec(layout: JointLayout, task_feature_names: Sequence[str],
                     task_feature_group: str = "command") -> ObservationSpec:
    names = layout.pos_names + layout.vel_names + tuple(task_feature_names)
    groups = (("positions",) * len(layout.pos_names) + ("velocities",) * len(layout.vel_names)
              + (task_feature_group,) * len(task_feature_names))
    return ObservationSpec(names, groups)
