"""Leg geometry read from a quadruped's MuJoCo model, and analytic 3-link leg kinematics.

The legs of the Unitree-style quadrupeds (A1, Go1) are a hip-abduction joint about the trunk's x axis,
then a thigh joint and a knee ("calf") joint about the y axis; the thigh frame sits a signed lateral
distance ``d`` from the abduction axis, thigh and calf hang straight down (lengths ``l1``, ``l2``) and
the foot is a sphere at the end of the calf. Everything is measured from the compiled model
(`quadruped_legs`), so any model with this structure works; the axes are checked.

Frames: a foot position ``p`` is the foot-sphere centre relative to the hip-abduction joint, expressed
in the trunk frame (x forward, y left, z up).

Forward kinematics (q1 abduction, q2 thigh, q3 knee)::

    x' = -l1 sin q2 - l2 sin(q2 + q3)           (sagittal plane after abduction)
    z' = -l1 cos q2 - l2 cos(q2 + q3)
    p  = R_x(q1) (x', d, z')

The inverse (`leg_ik`) solves the abduction angle from the y-z projection (the leg plane keeps the
lateral offset d), then the planar 2-link problem with the knee bent backwards (q3 < 0), as the
joint ranges of these robots require. Unreachable targets are pulled onto the workspace boundary
and the result is clipped to the joint ranges.
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

LEG_NAMES = ("FR", "FL", "RR", "RL")
#: joint name patterns tried in order; "{leg}" is replaced by the leg's name
_JOINT_PATTERNS = (("{leg}_hip_joint", "{leg}_thigh_joint", "{leg}_calf_joint"),)
_MIN_KNEE = 0.05        # rad: keep the knee this far from straight (singular) in the IK


@dataclass(frozen=True)
class LegGeometry:
    """One leg, measured from the model. Positions are in the trunk frame (metres)."""

    name: str
    joint_ids: tuple[int, int, int]
    qpos_adr: np.ndarray            # (3,) int
    dof_adr: np.ndarray             # (3,) int
    actuator_ids: np.ndarray        # (3,) int, -1 where a joint has no actuator
    hip_pos: np.ndarray             # (3,) abduction-joint position in the trunk frame
    d: float                        # signed lateral offset of the thigh frame (+ left)
    l1: float                       # thigh length
    l2: float                       # calf length (knee to foot-sphere centre)
    foot_geom: int
    foot_radius: float
    q_lo: np.ndarray                # (3,) joint lower limits
    q_hi: np.ndarray                # (3,) joint upper limits

    @property
    def nominal_foot(self) -> np.ndarray:
        """Foot position straight below the thigh joint (trunk frame, relative to the trunk origin), z = 0."""
        return np.array([self.hip_pos[0], self.hip_pos[1] + self.d, 0.0])


def _find(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    return mujoco.mj_name2id(model, kind, name)


def _body_offset(model: mujoco.MjModel, body: int, ancestor: int) -> tuple[np.ndarray, np.ndarray]:
    """Position and rotation of ``body`` relative to ``ancestor`` at qpos0 (chain of body_pos/body_quat)."""
    pos, rot = np.zeros(3), np.eye(3)
    chain = []
    b = body
    while b != ancestor:
        if b == 0:
            raise ValueError("body is not a descendant of the given ancestor")
        chain.append(b)
        b = int(model.body_parentid[b])
    for b in reversed(chain):
        r = np.zeros(9)
        mujoco.mju_quat2Mat(r, model.body_quat[b])
        pos = pos + rot @ model.body_pos[b]
        rot = rot @ r.reshape(3, 3)
    return pos, rot


def quadruped_legs(model: mujoco.MjModel, trunk_body: int | None = None) -> list[LegGeometry]:
    """The four legs (FR, FL, RR, RL) of a Unitree-style quadruped model; ValueError if the model differs."""
    if trunk_body is None:
        trunk_body = int(model.jnt_bodyid[0])
    legs = []
    for leg in LEG_NAMES:
        ids = None
        for pattern in _JOINT_PATTERNS:
            cand = [_find(model, mujoco.mjtObj.mjOBJ_JOINT, p.format(leg=leg)) for p in pattern]
            if min(cand) >= 0:
                ids = tuple(int(c) for c in cand)
                break
        if ids is None:
            raise ValueError(f"model has no {leg}_hip_joint/{leg}_thigh_joint/{leg}_calf_joint: not a "
                             f"Unitree-style quadruped")
        bodies = [int(model.jnt_bodyid[j]) for j in ids]
        for j, axis in zip(ids, ((1, 0, 0), (0, 1, 0), (0, 1, 0))):
            if not np.allclose(model.jnt_axis[j], axis) or not np.allclose(model.jnt_pos[j], 0):
                raise ValueError(f"joint {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)} has axis "
                                 f"{model.jnt_axis[j]} / pos {model.jnt_pos[j]}; expected axis {axis} at the body origin")
        hip_pos, hip_rot = _body_offset(model, bodies[0], trunk_body)
        thigh_pos, thigh_rot = _body_offset(model, bodies[1], bodies[0])
        calf_pos, calf_rot = _body_offset(model, bodies[2], bodies[1])
        for rot in (hip_rot, thigh_rot, calf_rot):
            if not np.allclose(rot, np.eye(3), atol=1e-9):
                raise ValueError(f"leg {leg}: rotated body frames are not supported")
        if abs(thigh_pos[0]) > 1e-9 or abs(thigh_pos[2]) > 1e-9 or abs(calf_pos[0]) > 1e-9 or abs(calf_pos[1]) > 1e-9:
            raise ValueError(f"leg {leg}: thigh/calf offsets {thigh_pos}/{calf_pos} are not a planar 3-link leg")
        # the foot: the sphere geom of the calf body that lies lowest
        spheres = [g for g in range(model.ngeom) if model.geom_bodyid[g] == bodies[2]
                   and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE]
        if not spheres:
            raise ValueError(f"leg {leg}: the calf body has no sphere (foot) geom")
        foot = min(spheres, key=lambda g: model.geom_pos[g][2])
        fpos = model.geom_pos[foot]
        if abs(fpos[0]) > 1e-9 or abs(fpos[1]) > 1e-9:
            raise ValueError(f"leg {leg}: the foot is not straight below the knee")
        actuators = np.full(3, -1, dtype=np.int64)
        for a in range(model.nu):
            if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT and int(model.actuator_trnid[a, 0]) in ids:
                actuators[ids.index(int(model.actuator_trnid[a, 0]))] = a
        legs.append(LegGeometry(
            name=leg, joint_ids=ids,
            qpos_adr=np.array([model.jnt_qposadr[j] for j in ids]),
            dof_adr=np.array([model.jnt_dofadr[j] for j in ids]),
            actuator_ids=actuators, hip_pos=hip_pos.copy(), d=float(thigh_pos[1]),
            l1=float(-calf_pos[2]), l2=float(-fpos[2]), foot_geom=int(foot),
            foot_radius=float(model.geom_size[foot][0]),
            q_lo=np.array([model.jnt_range[j][0] if model.jnt_limited[j] else -np.inf for j in ids]),
            q_hi=np.array([model.jnt_range[j][1] if model.jnt_limited[j] else np.inf for j in ids])))
    return legs


def leg_fk(leg: LegGeometry, q: np.ndarray) -> np.ndarray:
    """Foot-sphere centre relative to the abduction joint, trunk frame."""
    q1, q2, q3 = q
    xs = -leg.l1 * np.sin(q2) - leg.l2 * np.sin(q2 + q3)
    zs = -leg.l1 * np.cos(q2) - leg.l2 * np.cos(q2 + q3)
    c, s = np.cos(q1), np.sin(q1)
    return np.array([xs, c * leg.d - s * zs, s * leg.d + c * zs])


def leg_jacobian(leg: LegGeometry, q: np.ndarray) -> np.ndarray:
    """d(leg_fk)/dq, (3, 3): columns are the abduction, thigh and knee joints."""
    q1, q2, q3 = q
    l1, l2, d = leg.l1, leg.l2, leg.d
    xs = -l1 * np.sin(q2) - l2 * np.sin(q2 + q3)
    zs = -l1 * np.cos(q2) - l2 * np.cos(q2 + q3)
    dxs = np.array([-l1 * np.cos(q2) - l2 * np.cos(q2 + q3), -l2 * np.cos(q2 + q3)])   # d/dq2, d/dq3
    dzs = np.array([l1 * np.sin(q2) + l2 * np.sin(q2 + q3), l2 * np.sin(q2 + q3)])
    c, s = np.cos(q1), np.sin(q1)
    J = np.zeros((3, 3))
    J[:, 0] = [0.0, -s * d - c * zs, c * d - s * zs]
    J[0, 1:] = dxs
    J[1, 1:] = -s * dzs
    J[2, 1:] = c * dzs
    return J


def leg_ik(leg: LegGeometry, p: np.ndarray, clip: bool = True) -> np.ndarray:
    """Joint angles (abduction, thigh, knee) that put the foot at ``p`` (relative to the abduction joint,
    trunk frame); knee bent backwards. Targets out of reach are moved onto the workspace boundary."""
    x, y, z = float(p[0]), float(p[1]), float(p[2])
    d, l1, l2 = leg.d, leg.l1, leg.l2
    # abduction: the leg plane keeps the lateral offset d; the in-plane height z' < 0
    r_yz2 = y * y + z * z
    zs2 = max(r_yz2 - d * d, 1e-8)
    zs = -np.sqrt(zs2)
    q1 = np.arctan2(z, y) - np.arctan2(zs, d)
    q1 = (q1 + np.pi) % (2 * np.pi) - np.pi
    # planar two-link problem in (x, zs)
    reach = np.hypot(x, zs)
    max_reach = np.sqrt(l1 * l1 + l2 * l2 + 2 * l1 * l2 * np.cos(_MIN_KNEE))
    min_reach = abs(l1 - l2) + 1e-3
    if reach > max_reach or reach < min_reach:
        scale = np.clip(reach, min_reach, max_reach) / max(reach, 1e-9)
        x, zs, reach = x * scale, zs * scale, np.clip(reach, min_reach, max_reach)
    cos_k = (reach * reach - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    q3 = -np.arccos(np.clip(cos_k, -1.0, 1.0))
    a, b = l1 + l2 * np.cos(q3), l2 * np.sin(q3)
    q2 = np.arctan2(-x, -zs) - np.arctan2(b, a)
    q = np.array([q1, q2, q3])
    return np.clip(q, leg.q_lo, leg.q_hi) if clip else q


__all__ = ["LEG_NAMES", "LegGeometry", "quadruped_legs", "leg_fk", "leg_jacobian", "leg_ik"]
