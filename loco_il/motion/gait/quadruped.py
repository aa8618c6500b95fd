"""What the trot needs to know about an env: whether it is a quadruped, its goal speed, and a fingerprint of
the model the generated motion depends on (part of the cache keys of the data and experts built from it)."""
from __future__ import annotations

import hashlib
from typing import Any

import numpy as np


def is_quadruped(env: Any) -> bool:
    """True for an env, Body or Task-ID of the quadruped family (``body.family == "quadruped"``), the bodies
    the trot walks."""
    if isinstance(env, str):
        from loco_il.environments.registry import get_body, parse_task_id
        env = get_body(parse_task_id(env).body)
    body = getattr(env, "body", env)
    return getattr(body, "family", None) == "quadruped"


def goal_speed(env: Any, default: float = 0.5) -> float:
    """The speed the task's reward asks for (m/s), else ``default``."""
    speed = getattr(getattr(env, "task", None), "reward", None)
    return float(getattr(speed, "speed", default))


def model_fingerprint(env: Any) -> str:
    """Hash of what the generated motion depends on in the compiled model and the start state."""
    m = env.model
    h = hashlib.sha256()
    for arr in (m.body_mass, m.body_pos, m.body_inertia, m.jnt_range, m.dof_damping, m.dof_armature,
                m.dof_frictionloss, m.geom_size, m.geom_friction, m.actuator_gainprm, m.actuator_biasprm,
                m.actuator_gear, m.actuator_ctrlrange, m.actuator_forcerange, np.array([m.opt.timestep]),
                np.array([env.n_substeps]), env._init_qpos if hasattr(env, "_init_qpos") else m.qpos0):
        h.update(np.ascontiguousarray(arr, dtype=np.float64).tobytes())
    return h.hexdigest()[:16]


__all__ = ["is_quadruped", "goal_speed", "model_fingerprint"]
