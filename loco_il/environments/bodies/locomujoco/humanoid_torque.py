"""LocoMuJoCo 0.4.1's torque and muscle humanoids (from OpenSim Gait2392-derived models).

Facts from LocoMuJoCo 0.4.1 `loco_mujoco/environments/humanoids/base_humanoid.py` (`BaseHumanoid`,
`HumanoidTorque` / `HumanoidMuscle` in humanoids.py):
* `BaseHumanoid.__init__(use_box_feet=True, disable_arms=True)`: `_get_xml_modifications` removes the
  foot joints subtalar_angle_l/r and mtp_angle_l/r (and, torque model only, their mot_* motors) and
  the 14 arm joints (arm_flex/add/rot, elbow_flex, pro_sup, wrist_flex, wrist_dev, l and r) with their
  14 mot_* motors, plus the `<joint>_constraint` equalities of removed joints. -> 19 joints,
  observation 36 (17 positions + 19 velocities); 13 torque actions (HumanoidTorque) or 92 muscle
  actions (HumanoidMuscle, see below).
* Box feet (`_add_box_feet_to_xml_handle`, alpha 0.5): a box geom of half-size (0.112, 0.03, 0.05)
  at pos (-0.09, 0.019, 0) in toes_l / toes_r, euler (0, +0.15, 0) left and (0, -0.15, 0) right; the
  original foot geoms r_foot, r_bofoot, l_foot, l_bofoot are made non-colliding.
* `_reorient_arms`: body quaternions humerus_l (1, -0.1, -1, -0.1), ulna_l (1, 0.6, 0, 0),
  humerus_r (1, 0.1, 1, -0.1), ulna_r (1, -0.6, 0, 0).
* `_has_fallen` (base_humanoid.py lines 145-157): pelvis_ty outside [-0.46, 0.1], pelvis_tilt outside
  [-pi/4.5, pi/12], pelvis_list outside [-pi/12, pi/8], pelvis_rotation outside [-pi/9, pi/9],
  lumbar_extension outside [-pi/4, pi/10], lumbar_bending outside [-pi/10, pi/10], lumbar_rotation
  outside [-pi/4.5, pi/4.5]. The pelvis body sits at z = 0.975, so the height band is [0.515, 1.075] m
  on the pelvis world z. Tasks walk (1.25 m/s) and run (2.5 m/s).
* The pelvis body is rotated 90 deg about x (OpenSim's y-up frame), so pelvis_ty is the vertical slide
  and pelvis_tx / pelvis_tz are the horizontal ones (the ones the observation leaves out).
* Muscles: the XML's default class gives `<muscle ctrlrange="0 1">` and then `<motor ctrlrange="-1 1">`;
  both set the one actuator default, so the compiled muscles have ctrlrange [-1, 1] (in LocoMuJoCo
  too): actions in [-1, 0] mean zero excitation, (0, 1] excite.

Start pose ("stand" keyframe, ours): qpos0 leaned forward by 0.07 rad (pelvis_tilt -0.07, both
ankle_angle +0.07; the feet stay flat within 0.5 deg, the ankle axis being oblique): at qpos0 the centre
of mass is 6.5 cm behind the middle of the box feet; leaned, it is over it. pelvis_ty -0.0088 puts the
box feet on the floor (measured with `mujoco.mj_geomDistance`). With zero action the robot stays up
for 0.34 s (torque) / 0.35 s (muscle).
"""
from __future__ import annotations

import mujoco
import numpy as np

from loco_il.environments.body import Body
from loco_il.environments.bodies.locomujoco.common import (STAND_KEY, RootJointFall, add_keyframe, humanoid_tasks,
                                                           locomujoco_body, pelvis_bounds, set_body_quats,
                                                           slide_to_height)
from loco_il.environments.registry import register_body

PELVIS_Z = 0.975    # humanoid_torque.xml / humanoid_muscle.xml: <body name="pelvis" pos="0 6.7e-17 0.975">
TORQUE_MODEL = "humanoid/humanoid_torque.xml"
MUSCLE_MODEL = "humanoid/humanoid_muscle.xml"

FOOT_JOINTS = ("subtalar_angle_l", "mtp_angle_l", "subtalar_angle_r", "mtp_angle_r")
FOOT_MOTORS = ("mot_subtalar_angle_l", "mot_mtp_angle_l", "mot_subtalar_angle_r", "mot_mtp_angle_r")
ARM_JOINTS = ("arm_flex_r", "arm_add_r", "arm_rot_r", "elbow_flex_r", "pro_sup_r", "wrist_flex_r", "wrist_dev_r",
              "arm_flex_l", "arm_add_l", "arm_rot_l", "elbow_flex_l", "pro_sup_l", "wrist_flex_l", "wrist_dev_l")
ARM_MOTORS = ("mot_shoulder_flex_r", "mot_shoulder_add_r", "mot_shoulder_rot_r", "mot_elbow_flex_r", "mot_pro_sup_r",
              "mot_wrist_flex_r", "mot_wrist_dev_r", "mot_shoulder_flex_l", "mot_shoulder_add_l",
              "mot_shoulder_rot_l", "mot_elbow_flex_l", "mot_pro_sup_l", "mot_wrist_flex_l", "mot_wrist_dev_l")
REMOVED_JOINTS = FOOT_JOINTS + ARM_JOINTS
ARM_QUATS = {"humerus_l": (1.0, -0.1, -1.0, -0.1), "ulna_l": (1.0, 0.6, 0.0, 0.0),
             "humerus_r": (1.0, 0.1, 1.0, -0.1), "ulna_r": (1.0, -0.6, 0.0, 0.0)}
BOX_HALF_SIZE = (0.112, 0.03, 0.05)
BOX_POS = (-0.09, 0.019, 0.0)
BOX_PITCH = {"l": 0.15, "r": -0.15}
OLD_FOOT_GEOMS = ("r_foot", "r_bofoot", "l_foot", "l_bofoot")

TERMINATION = RootJointFall(
    height_range=slide_to_height(PELVIS_Z, (-0.46, 0.1)),
    joint_bounds=pelvis_bounds(np.pi / 9) + (
                  ("lumbar_extension", -np.pi / 4, np.pi / 10),
                  ("lumbar_bending", -np.pi / 10, np.pi / 10),
                  ("lumbar_rotation", -np.pi / 4.5, np.pi / 4.5)))

STAND_POSE = {"pelvis_ty": -0.0088, "pelvis_tilt": -0.07, "ankle_angle_l": 0.07, "ankle_angle_r": 0.07}


def add_box_feet(spec: mujoco.MjSpec) -> None:
    """LocoMuJoCo's box feet: one box per toes body; the original foot meshes stop colliding."""
    for side, pitch in BOX_PITCH.items():
        toes = spec.body(f"toes_{side}")
        # rotation about y by `pitch` (LocoMuJoCo gives euler (0, pitch, 0) in radians)
        quat = [np.cos(pitch / 2), 0.0, np.sin(pitch / 2), 0.0]
        toes.add_geom(name=f"foot_box_{side}", type=mujoco.mjtGeom.mjGEOM_BOX, size=list(BOX_HALF_SIZE),
                      pos=list(BOX_POS), quat=quat, rgba=[0.5, 0.5, 0.5, 0.5])
    for name in OLD_FOOT_GEOMS:
        geom = spec.geom(name)
        geom.contype = 0
        geom.conaffinity = 0


def edit(spec: mujoco.MjSpec) -> None:
    """LocoMuJoCo's default edits (box feet, arms turned in) and our "stand" keyframe."""
    add_box_feet(spec)
    set_body_quats(spec, ARM_QUATS)
    add_keyframe(spec, STAND_POSE, STAND_KEY)


def _humanoid(name: str, model: str, actuators_to_remove: tuple[str, ...]) -> Body:
    return locomujoco_body(name, model, humanoid_tasks(TERMINATION, run=True, robot=name), "locomujoco/humanoid",
                           edit, joints_to_remove=REMOVED_JOINTS, actuators_to_remove=actuators_to_remove)


TORQUE_REMOVED_MOTORS = FOOT_MOTORS + ARM_MOTORS
MUSCLE_REMOVED_MOTORS = ARM_MOTORS
HUMANOID_TORQUE = _humanoid("HumanoidTorque", TORQUE_MODEL, TORQUE_REMOVED_MOTORS)
HUMANOID_MUSCLE = _humanoid("HumanoidMuscle", MUSCLE_MODEL, MUSCLE_REMOVED_MOTORS)

register_body(HUMANOID_TORQUE)
register_body(HUMANOID_MUSCLE)
