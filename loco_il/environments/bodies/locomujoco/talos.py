"""Talos (PAL Robotics) as LocoMuJoCo 0.4.1 configures it by default.

Facts from LocoMuJoCo 0.4.1 `loco_mujoco/environments/humanoids/talos.py`:
* `Talos.__init__(disable_arms=True, disable_back_joint=False)`: `_get_xml_modifications` removes the
  12 arm joints (l/r_arm_shz, shx, ely, elx, wry, wrx) and their `<joint>_actuator` motors; the back
  joints back_bkz and back_bky stay -> 18 joints, observation 34 (16 positions + 18 velocities),
  12 actions. With the arms disabled (and no weight) `_reorient_arms` sets the quaternions of
  arm_right_4_link and arm_left_4_link to (1, 0, -0.25, 0) so the elbows clear the hips.
  Tasks walk (1.25 m/s) and carry.
* carry (`Talos._add_weight`, `Talos.__init__(hold_weight=True)`): a body "weight" on torso_2_link holding
  a box geom of half-sizes (0.1, 0.25, 0.1) at (0.45, 0, -0.2) whose mass is one of 0.1, 1, 5, 10 kg, one
  model per mass, one drawn per episode; the arms hold it (body quaternions arm_right/left_4_link
  (1, 0, -0.65, 0), arm_right/left_6_link (1, 0, 0, 1), instead of the walking pose). The observation
  gains the mass: 35 entries.
* `_has_fallen` (talos.py lines 371-382): pelvis_ty outside [-0.3, 0.1], pelvis_tilt outside
  [-pi/4.5, pi/12], pelvis_list outside [-pi/12, pi/8], pelvis_rotation outside [-pi/10, pi/10],
  back_bky outside [-pi/4, pi/10], back_bkz outside [-pi/10, pi/10]. The pelvis body sits at
  z = 1.085 in talos.xml, so the height band is [0.785, 1.185] m on the pelvis world z.
* The model file's timestep is 0.002; LocoMuJoCo (and we) simulate at 0.001.

Licence: CC BY-NC-ND 4.0 - the model is fetched at run time from the LocoMuJoCo sdist, never shipped.
Start pose ("stand" keyframe, ours): qpos0 (centre of mass already over the feet) with pelvis_ty
+0.0011 so the foot boxes just touch the floor (measured with `mujoco.mj_geomDistance`; at qpos0 they
are 1.1 mm inside it). With zero torque the robot stays up for 0.42 s.
"""
from __future__ import annotations

import numpy as np

from loco_il.environments.bodies.locomujoco.common import (STAND_KEY, Load, RootJointFall, add_keyframe, carry_task,
                                                           humanoid_tasks, locomujoco_body, pelvis_bounds,
                                                           set_body_quats, slide_to_height)
from loco_il.environments.registry import register_body

MODEL = "talos/talos.xml"
PELVIS_Z = 1.085    # talos.xml: <body name="pelvis" pos="0 0 1.085">

REMOVED_JOINTS = ("l_arm_shz", "l_arm_shx", "l_arm_ely", "l_arm_elx", "l_arm_wry", "l_arm_wrx",
                  "r_arm_shz", "r_arm_shx", "r_arm_ely", "r_arm_elx", "r_arm_wry", "r_arm_wrx")
REMOVED_ACTUATORS = tuple(f"{j}_actuator" for j in REMOVED_JOINTS)
ARM_QUATS = {"arm_right_4_link": (1.0, 0.0, -0.25, 0.0), "arm_left_4_link": (1.0, 0.0, -0.25, 0.0)}

TERMINATION = RootJointFall(
    height_range=slide_to_height(PELVIS_Z, (-0.3, 0.1)),
    joint_bounds=pelvis_bounds(np.pi / 10) + (
                  ("back_bky", -np.pi / 4, np.pi / 10),
                  ("back_bkz", -np.pi / 10, np.pi / 10)))

LOAD = Load(parent="torso_2_link", half_size=(0.1, 0.25, 0.1), pos=(0.45, 0.0, -0.2),
            body_quats={"arm_right_4_link": (1.0, 0.0, -0.65, 0.0), "arm_left_4_link": (1.0, 0.0, -0.65, 0.0),
                        "arm_right_6_link": (1.0, 0.0, 0.0, 1.0), "arm_left_6_link": (1.0, 0.0, 0.0, 1.0)})

STAND_POSE = {"pelvis_ty": 0.0011}


def _edit(spec) -> None:
    set_body_quats(spec, ARM_QUATS)
    add_keyframe(spec, STAND_POSE, STAND_KEY)


TASKS = {**humanoid_tasks(TERMINATION, run=False, robot="Talos"), "carry": carry_task(TERMINATION, "Talos", LOAD)}
TALOS = locomujoco_body("Talos", MODEL, TASKS, "locomujoco/talos",
                        _edit, joints_to_remove=REMOVED_JOINTS, actuators_to_remove=REMOVED_ACTUATORS)

register_body(TALOS)
