"""Atlas (Boston Dynamics, model from drcsim via Roboti) as LocoMuJoCo 0.4.1 configures it by default.

Facts from LocoMuJoCo 0.4.1 `loco_mujoco/environments/humanoids/atlas.py`:
* `Atlas.__init__(disable_arms=True, disable_back_joint=True)`: `_get_xml_modifications` removes the
  12 arm joints (l/r_arm_shz, shx, ely, elx, wry, wrx) and the 3 back joints (back_bkz, bky, bkx) with
  their `<joint>_actuator` motors -> 16 joints left, observation 30 (14 positions + 16 velocities),
  10 actions. Tasks walk (1.25 m/s) and carry.
* carry (`Atlas._add_weight`, `Atlas.__init__(hold_weight=True)`): a body "weight" on utorso holding a
  box geom of half-sizes (0.1, 0.27, 0.1) at (0.72, 0, -0.25) whose mass is one of 0.1, 1, 5, 10 kg, one
  model per mass, one drawn per episode; the arms are turned to hold it (body quaternions r_clav
  (1, 0, -0.35, 0), l_clav (0, -0.35, 0, 1)). The observation gains the mass: 31 entries.
* `_has_fallen` (atlas.py lines 381-384): pelvis_ty outside [-0.3, 0.1], pelvis_tilt outside
  [-pi/4.5, pi/12], pelvis_list outside [-pi/12, pi/8], pelvis_rotation outside [-pi/10, pi/10]
  (the back bounds apply only with the back joint enabled). The pelvis body sits at z = 0.94 in
  atlas.xml, so the height band is [0.64, 1.04] m on the pelvis world z (see `common.py`).

Start pose ("stand" keyframe, ours): qpos0 leaned forward by 0.04 rad (pelvis_tilt -0.04, both
ankle_angle +0.04, so the feet stay flat) to put the centre of mass over the middle of the feet (at
qpos0 it is 4 cm behind it), and pelvis_ty -0.0046 so the foot boxes just touch the floor (measured
with `mujoco.mj_geomDistance`). With zero torque the robot stays up for 0.37 s before the
tilt bound ends the episode; a joint-space PD hold keeps it standing (tested for 0.5 s).
"""
from __future__ import annotations

import numpy as np

from loco_il.environments.bodies.locomujoco.common import (STAND_KEY, Load, RootJointFall, add_keyframe, carry_task,
                                                           humanoid_tasks, locomujoco_body, pelvis_bounds,
                                                           slide_to_height)
from loco_il.environments.registry import register_body

MODEL = "atlas/atlas.xml"
PELVIS_Z = 0.94     # atlas.xml: <body name="pelvis" pos="0 0 0.94">

ARM_JOINTS = ("l_arm_shz", "l_arm_shx", "l_arm_ely", "l_arm_elx", "l_arm_wry", "l_arm_wrx",
              "r_arm_shz", "r_arm_shx", "r_arm_ely", "r_arm_elx", "r_arm_wry", "r_arm_wrx")
BACK_JOINTS = ("back_bkz", "back_bky", "back_bkx")
REMOVED_JOINTS = ARM_JOINTS + BACK_JOINTS
REMOVED_ACTUATORS = tuple(f"{j}_actuator" for j in REMOVED_JOINTS)

TERMINATION = RootJointFall(
    height_range=slide_to_height(PELVIS_Z, (-0.3, 0.1)),
    joint_bounds=pelvis_bounds(np.pi / 10))

LOAD = Load(parent="utorso", half_size=(0.1, 0.27, 0.1), pos=(0.72, 0.0, -0.25),
            body_quats={"r_clav": (1.0, 0.0, -0.35, 0.0), "l_clav": (0.0, -0.35, 0.0, 1.0)})

STAND_POSE = {"pelvis_ty": -0.0046, "pelvis_tilt": -0.04, "ankle_angle_l": 0.04, "ankle_angle_r": 0.04}


def _edit(spec) -> None:
    add_keyframe(spec, STAND_POSE, STAND_KEY)


TASKS = {**humanoid_tasks(TERMINATION, run=False, robot="Atlas"), "carry": carry_task(TERMINATION, "Atlas", LOAD)}
ATLAS = locomujoco_body("Atlas", MODEL, TASKS, "locomujoco/atlas",
                        _edit, joints_to_remove=REMOVED_JOINTS, actuators_to_remove=REMOVED_ACTUATORS)

register_body(ATLAS)
