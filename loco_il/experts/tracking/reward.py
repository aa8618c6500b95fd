"""DeepMimic's tracking reward (Peng et al. 2018, sec. 5.2, eq. 6-10), for training tracking experts only.

    r = w_pose exp(-k_pose sum_j (q_j - q_ref_j)^2 + root orientation angle^2)
      + w_vel  exp(-k_vel  sum_j (dq_j - dq_ref_j)^2)
      + w_ee   exp(-k_ee   sum_e |(p_e - p_root) - (p_ref_e - p_ref_root)|^2)
      + w_root exp(-k_root |p_root - p_ref_root|^2)
      (+ w_task * the env's task reward, ours, 0 by default)

j runs over the actuated joints, e over the feet bodies (`reference.END_EFFECTOR_KEYPOINTS`); DeepMimic's
centre-of-mass term is taken on the root body, whose reference position carries the cycle drift and is anchored
to where the episode started (`anchor`). With the weights summing to 1 the reward is 1 exactly on the reference
and falls with every error. The env's task reward stays the evaluation reward.
"""
from __future__ import annotations

from typing import Sequence

import mujoco
import numpy as np

from loco_il.experts.tracking.reference import ReferenceMotion
from loco_il.experts.tracking.settings import TrackingSettings


class TrackingReward:
    """`reward(data, phase, anchor, rate) -> (reward, terms)` for one compiled model (see the module docstring);
    `rate` is the phase clock's speed (`TrackingController.rate`), which scales the reference velocities."""

    def __init__(self, model: mujoco.MjModel, reference: ReferenceMotion, settings: TrackingSettings):
        self.reference, self.settings = reference, settings
        self.root = int(model.jnt_bodyid[0])
        self.ee_ids = _body_ids(model, reference.ee_bodies)
        self._orientation_error = np.zeros(3)

    def __call__(self, data: mujoco.MjData, phase: float, anchor: np.ndarray,
                 rate: float = 1.0) -> tuple[float, dict[str, float]]:
        ref, s = self.reference, self.settings
        q_ref, dq_ref = ref.targets(phase)
        dq_ref = rate * dq_ref
        root_ref, quat_ref, ee_ref = ref.kinematics(phase)
        root_ref[:2] += anchor
        mujoco.mju_subQuat(self._orientation_error, data.xquat[self.root], quat_ref)
        pose_err = float(np.sum((data.qpos[ref.actuated_qpos] - q_ref) ** 2)
                         + self._orientation_error @ self._orientation_error)
        vel_err = float(np.sum((data.qvel[ref.actuated_qvel] - dq_ref) ** 2))
        root = data.xpos[self.root]
        ee_err = float(np.sum((data.xpos[self.ee_ids] - root - ee_ref) ** 2))
        root_err = float(np.sum((root - root_ref) ** 2))
        terms = {"pose": np.exp(-s.k_pose * pose_err), "vel": np.exp(-s.k_vel * vel_err),
                 "ee": np.exp(-s.k_ee * ee_err), "root": np.exp(-s.k_root * root_err)}
        reward = s.w_pose * terms["pose"] + s.w_vel * terms["vel"] + s.w_ee * terms["ee"] + s.w_root * terms["root"]
        terms["root_error"] = float(np.sqrt(root_err))
        return float(reward), {k: float(v) for k, v in terms.items()}


def _body_ids(model: mujoco.MjModel, names: Sequence[str]) -> np.ndarray:
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in names]
    missing = [n for n, i in zip(names, ids) if i < 0]
    if missing:
        raise KeyError(f"the reference names end-effector bodies the model lacks: {missing}")
    return np.array(ids, dtype=np.intp)
