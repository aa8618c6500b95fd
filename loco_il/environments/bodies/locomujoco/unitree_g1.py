"""Unitree G1 as LocoMuJoCo 0.4.1 configures it by default.

Facts from LocoMuJoCo 0.4.1 `loco_mujoco/environments/humanoids/unitreeG1.py`:
* `UnitreeG1.__init__(disable_arms=False, disable_back_joint=False)`: nothing is removed by default ->
  29 joints, observation 56 (27 positions + 29 velocities), 23 actions (motors named like their
  joints, control range in N m). Tasks walk (1.25 m/s) and run (2.5 m/s).
* `_has_fallen` (unitreeG1.py lines 372-375): pelvis_ty outside [-0.3, 0.1], pelvis_tilt outside
  [-pi/4.5, pi/12], pelvis_list outside [-pi/12, pi/8], pelvis_rotation outside [-pi/8, pi/8].
  The pelvis body sits at z = 0.755 in g1.xml, so the height band is [0.455, 0.855] m on the pelvis
  world z.
* The model file's timestep is 0.002; LocoMuJoCo (and we) simulate at 0.001.

Start pose ("stand" keyframe, ours): qpos0 (centre of mass already over the middle of the feet) with
pelvis_ty -0.0043 so the foot collision spheres just touch the floor (measured with
`mujoco.mj_geomDistance`). With zero torque the robot stays up for 0.35 s.
"""
from __future__ import annotations

import numpy as np

from loco_il.environments.bodies.locomujoco.common import (STAND_KEY, RootJointFall, add_keyframe, humanoid_tasks,
                                                           locomujoco_body, pelvis_bounds, slide_to_height)
from loco_il.environments.registry import register_body

MODEL = "unitree_g1/g1.xml"
PELVIS_Z = 0.755    # g1.xml: <body name="pelvis" pos="0 0 0.755">

TERMINATION = RootJointFall(
    height_range=slide_to_height(PELVIS_Z, (-0.3, 0.1)),
    joint_bounds=pelvis_bounds(np.pi / 8))

STAND_POSE = {"pelvis_ty": -0.0043}


def _edit(spec) -> None:
    add_keyframe(spec, STAND_POSE, STAND_KEY)


UNITREE_G1 = locomujoco_body("UnitreeG1", MODEL, humanoid_tasks(TERMINATION, run=True, robot="UnitreeG1"),
                             "locomujoco/unitree_g1", _edit)

register_body(UNITREE_G1)
