"""LocoMuJoCo 0.4.1's four-ages humanoids: the torque and muscle humanoids in four body sizes.

Facts from LocoMuJoCo 0.4.1 `loco_mujoco/environments/humanoids/base_humanoid_4_ages.py`
(`BaseHumanoid4Ages`, `HumanoidTorque4Ages` / `HumanoidMuscle4Ages` in humanoids.py):
* Sizes (`_default_scalings`): 0.4 (a toddler who just started walking), 0.6 (~5 years), 0.8 (~12 years),
  1.0 (an adult); one model per size. Task-IDs `<Body>.<walk|run>.<mode>.<dataset>` with the modes
  "all" (one size drawn per episode, uniformly: `LocoEnv.reset` with `random_env_reset`) and "1".."4"
  (one size: 0.4, 0.6, 0.8, 1.0). HumanoidTorque4Ages offers real and perfect datasets, HumanoidMuscle4Ages
  real only (`valid_task_confs`).
* `scale_body(scaling s)`: every mesh scaled by s except the head's (hat_skull, hat_jaw), whose geoms move
  to (0, -0.5 (1 - s), 0) instead; every body position scaled by s, body mass by s^3, inertia by s^5;
  muscle model: site positions by s, muscle force by s^2 and length range by s; torque model: motor gear
  by s^2. The box feet (`_add_box_feet_to_xml_handle(scaling)`) have size and position scaled by s.
  Ours scales the same, plus what LocoMuJoCo leaves out so that each size is the adult shrunk exactly:
  body centre-of-mass offsets (ipos), non-mesh geom sizes and positions, joint anchors and site sizes.
* Observation (`_create_observation`, mushroom-rl `MultiMuJoCo._get_env_id_map`): the humanoid's 36 entries,
  then the size index (0..3) as 2 bits, most significant first: 38 entries (group "env_type").
* Reward (`MultiTargetVelocityReward`): exp(-(v_x - s v*)^2), v* = 1.25 m/s (walk) or 2.5 m/s (run).
* Termination: `BaseHumanoid._has_fallen` unchanged for every size: the bounds apply to the vertical
  slide pelvis_ty itself ([-0.46, 0.1] m, not scaled), the pelvis and lumbar angles as for the adult.
* Datasets: states lack the size entries (LocoMuJoCo slices them with a mask); its "all" dataset holds the
  trajectories of every size in the size order. Ours: full observations like every dataset here, with the
  size entries of each episode's size (hide them with `hide=("env_type",)`); motion is retargeted to the
  adult, and the state of size s is the adult's with the root slides (positions and velocities) scaled by
  s, joint angles unchanged: exactly the adult's motion on the shrunk body.
"""
from __future__ import annotations

from functools import partial

import mujoco
import numpy as np

from loco_il.environments.bodies.locomujoco import humanoid_torque as adult
from loco_il.environments.bodies.locomujoco.common import (HORIZON, RUN_SPEED, WALK_SPEED, RootJointFall,
                                                           locomujoco_body)
from loco_il.environments.body import Body
from loco_il.environments.registry import register_body
from loco_il.environments.tasks import EpisodeDraw, ScaledTargetVelocityReward, Task

AGE_SCALES = (0.4, 0.6, 0.8, 1.0)
MODES = {"all": (0, 1, 2, 3), "1": (0,), "2": (1,), "3": (2,), "4": (3,)}
HEAD_GEOMS = ("hat_skull", "hat_jaw")
SIZE_NAMES = ("size_bit_0", "size_bit_1")

TERMINATION = RootJointFall(height_range=(-0.46, 0.1), joint_bounds=adult.TERMINATION.joint_bounds,
                            slide_relative=True)


def size_bits(scale: float) -> np.ndarray:
    """The size index as 2 bits, most significant first (mushroom-rl `_get_env_id_map`)."""
    index = AGE_SCALES.index(scale)
    return np.array([(index >> 1) & 1, index & 1], dtype=np.float64)


def scale_humanoid(spec: mujoco.MjSpec, scale: float, muscles: bool) -> None:
    """Shrink the humanoid by `scale`: lengths by s, masses by s^3, inertias by s^5, muscle forces / motor
    gears by s^2, muscle length ranges by s (the head keeps its size, LocoMuJoCo's choice)."""
    if scale not in AGE_SCALES:
        raise ValueError(f"body scale {scale} is not one of the four ages {AGE_SCALES}")
    s = float(scale)
    for mesh in spec.meshes:
        if mesh.name not in HEAD_GEOMS:
            mesh.scale = np.asarray(mesh.scale) * s
    for geom in spec.geoms:
        if geom.name in HEAD_GEOMS:
            geom.pos = [0.0, -0.5 * (1.0 - s), 0.0]
        elif geom.parent.name != "world":   # the floor stays
            geom.pos = np.asarray(geom.pos) * s
            if geom.type != mujoco.mjtGeom.mjGEOM_MESH:
                geom.size = np.asarray(geom.size) * s
    for body in spec.bodies:
        if body.name == "world":
            continue
        body.pos = np.asarray(body.pos) * s
        body.ipos = np.asarray(body.ipos) * s
        body.mass = body.mass * s ** 3
        full = np.asarray(body.fullinertia)
        if np.all(np.isfinite(full)) and full.any():
            body.fullinertia = full * s ** 5
        body.inertia = np.asarray(body.inertia) * s ** 5
    for joint in spec.joints:
        joint.pos = np.asarray(joint.pos) * s
    for site in spec.sites:
        site.pos = np.asarray(site.pos) * s
        site.size = np.asarray(site.size) * s
    for act in spec.actuators:
        if muscles and act.dyntype == mujoco.mjtDyn.mjDYN_MUSCLE:
            gain, bias = np.asarray(act.gainprm), np.asarray(act.biasprm)
            gain[2] *= s ** 2          # peak active force (gainprm = range, force, scale, ...)
            bias[2] *= s ** 2
            act.gainprm, act.biasprm = gain, bias
            act.lengthrange = np.asarray(act.lengthrange) * s
        elif not muscles:
            act.gear = np.asarray(act.gear) * s ** 2


def scale_state(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray,
                scale: float) -> tuple[np.ndarray, np.ndarray]:
    """The adult's state on the body of size `scale`: root slides (positions, velocities) scaled, angles kept."""
    qpos, qvel = np.array(qpos, dtype=np.float64), np.array(qvel, dtype=np.float64)
    slides = model.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE
    qpos[model.jnt_qposadr[slides]] *= scale
    qvel[model.jnt_dofadr[slides]] *= scale
    return qpos, qvel


def _tasks(name: str, muscles: bool) -> dict[str, Task]:
    draw = EpisodeDraw(values=AGE_SCALES, edit=partial(scale_humanoid, muscles=muscles), names=SIZE_NAMES,
                       group="env_type", features=size_bits, modes=MODES, default_mode="all",
                       reference=AGE_SCALES.index(1.0), state_map=scale_state)
    return {task: Task(ScaledTargetVelocityReward(speed), TERMINATION, horizon=HORIZON, draw=draw,
                       description=f"{name}: {task} forward at {speed} m/s times the body size "
                                   f"({', '.join(map(str, AGE_SCALES))}; LocoMuJoCo 4Ages {task})")
            for task, speed in (("walk", WALK_SPEED), ("run", RUN_SPEED))}


def _four_ages(name: str, model: str, actuators_to_remove: tuple[str, ...], muscles: bool) -> Body:
    return locomujoco_body(name, model, _tasks(name, muscles), "locomujoco/humanoid", adult.edit,
                           joints_to_remove=adult.REMOVED_JOINTS, actuators_to_remove=actuators_to_remove)


HUMANOID_TORQUE_4AGES = _four_ages("HumanoidTorque4Ages", adult.TORQUE_MODEL, adult.TORQUE_REMOVED_MOTORS, False)
HUMANOID_MUSCLE_4AGES = _four_ages("HumanoidMuscle4Ages", adult.MUSCLE_MODEL, adult.MUSCLE_REMOVED_MOTORS, True)

register_body(HUMANOID_TORQUE_4AGES)
register_body(HUMANOID_MUSCLE_4AGES)
