"""Unitree H1 as LocoMuJoCo 0.4.1 configures it by default.

Facts from LocoMuJoCo 0.4.1 `loco_mujoco/environments/humanoids/unitreeH1.py`:
* `UnitreeH1.__init__(disable_arms=True, disable_back_joint=False)`: `_get_xml_modifications` removes
  the 8 arm joints (l/r_arm_shy, shx, shz, left/right_elbow) and their `<joint>_actuator` motors; the
  torso joint back_bkz stays -> 17 joints, observation 32 (15 positions + 17 velocities), 11 actions.
  With the arms disabled (and no weight) `_reorient_arms` sets body quaternions
  left_shoulder_pitch_link (1, 0.25, 0.1, 0), right_shoulder_pitch_link (1, -0.25, 0.1, 0),
  left_elbow_link and right_elbow_link (1, 0, 0.25, 0). Tasks walk (1.25 m/s), run (2.5 m/s), carry.
* carry (`UnitreeH1._add_weight`, `UnitreeH1.__init__(hold_weight=True)`): a body "weight" on torso_link
  holding a box geom of half-sizes (0.1, 0.18, 0.1) at (0.35, 0, 0.1) whose mass is one of 0.1, 1, 5,
  10 kg, one model per mass, one drawn per episode; the arms keep the model's pose (h1.xml: shoulder
  pitch links (0.976296, +-0.216438, 0, 0), elbows unrotated) since `_reorient_arms` is skipped with a
  weight. The observation gains the mass: 33 entries.
* `_has_fallen` (unitreeH1.py lines 362-365): pelvis_ty outside [-0.3, 0.1], pelvis_tilt outside
  [-pi/4.5, pi/12], pelvis_list outside [-pi/12, pi/8], pelvis_rotation outside [-pi/8, pi/8].
  The pelvis body sits at z = 1.045 in h1.xml, so the height band is [0.745, 1.145] m on the pelvis
  world z.
* The model file's timestep is 0.002; LocoMuJoCo (and we) simulate at 0.001.

Start pose ("stand" keyframe, ours): qpos0 leaned forward by 0.1 rad (pelvis_tilt -0.1, both
ankle_angle -0.1, so the feet stay flat): at qpos0 the centre of mass is over the heel edge of the
ankle-link collision meshes; leaned, it is over their middle. pelvis_ty -0.0017 puts the feet on the
floor (measured with `mujoco.mj_geomDistance`). With zero torque the robot stays up for 0.35 s.
"""
from __future__ import annotations

import numpy as np

from loco_il.environments.bodies.locomujoco.common import (STAND_KEY, Load, RootJointFall, add_keyframe, carry_task,
                                                           humanoid_tasks, locomujoco_body, pelvis_bounds,
                                                           set_body_quats, slide_to_height)
from loco_il.environments.registry import register_body

MODEL = "unitree_h1/h1.xml"
PELVIS_Z = 1.045    # h1.xml: <body name="pelvis" pos="0 0 1.045">

REMOVED_JOINTS = ("l_arm_shy", "l_arm_shx", "l_arm_shz", "left_elbow",
                  "r_arm_shy", "r_arm_shx", "r_arm_shz", "right_elbow")
REMOVED_ACTUATORS = tuple(f"{j}_actuator" for j in REMOVED_JOINTS)
ARM_QUATS = {"left_shoulder_pitch_link": (1.0, 0.25, 0.1, 0.0), "right_elbow_link": (1.0, 0.0, 0.25, 0.0),
             "right_shoulder_pitch_link": (1.0, -0.25, 0.1, 0.0), "left_elbow_link": (1.0, 0.0, 0.25, 0.0)}

TERMINATION = RootJointFall(
    height_range=slide_to_height(PELVIS_Z, (-0.3, 0.1)),
    joint_bounds=pelvis_bounds(np.pi / 8))

MODEL_ARM_QUATS = {"left_shoulder_pitch_link": (0.976296, 0.216438, 0.0, 0.0), "left_elbow_link": (1.0, 0.0, 0.0, 0.0),
                   "right_shoulder_pitch_link": (0.976296, -0.216438, 0.0, 0.0),
                   "right_elbow_link": (1.0, 0.0, 0.0, 0.0)}
LOAD = Load(parent="torso_link", half_size=(0.1, 0.18, 0.1), pos=(0.35, 0.0, 0.1), body_quats=MODEL_ARM_QUATS)

STAND_POSE = {"pelvis_ty": -0.0017, "pelvis_tilt": -0.1, "ankle_angle_l": -0.1, "ankle_angle_r": -0.1}


def _edit(spec) -> None:
    set_body_quats(spec, ARM_QUATS)
    add_keyframe(spec, STAND_POSE, STAND_KEY)


TASKS = {**humanoid_tasks(TERMINATION, run=True, robot="UnitreeH1"),
         "carry": carry_task(TERMINATION, "UnitreeH1", LOAD)}
UNITREE_H1 = locomujoco_body("UnitreeH1", MODEL, TASKS,
                             "locomujoco/unitree_h1", _edit,
                             joints_to_remove=REMOVED_JOINTS, actuators_to_remove=REMOVED_ACTUATORS)

register_body(UNITREE_H1)
