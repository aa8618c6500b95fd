"""Shared by the retargeting tests (`tests/motion/mocap`) and the `real` dataset tests (`tests/datasets`):
a cached env that skips when a robot's model files are unavailable, a synthetic walking clip, quality bounds."""
from __future__ import annotations

import numpy as np
import pytest

from loco_il import LocoEnv
from loco_il.motion.mocap import MotionClip, humanoid3d_skeleton, quat_from_axis_angle

KEYPOINT_BOUND = 0.08      # m, mean keypoint error
PENETRATION_BOUND = 0.01   # m, deepest sole point below the ground

_ENVS: dict = {}


def cached_env(task_id: str) -> LocoEnv:
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
