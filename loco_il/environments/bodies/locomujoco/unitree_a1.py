"""Unitree A1 (torque control) as LocoMuJoCo 0.4.1 configures it by default.

Facts from LocoMuJoCo 0.4.1 `loco_mujoco/environments/quadrupeds/unitreeA1.py`:
* `UnitreeA1.__init__(action_mode="torque", default_target_velocity=0.5)` loads
  quadrupeds/unitree_a1_torque.xml and removes nothing: 18 joints (trunk_tx/ty/tz, trunk_list/tilt/
  rotation, 3 per leg), 12 motors. Its observation is 16 positions + 18 velocities, then the goal
  direction as (cos, sin) and the goal speed (`_create_observation` / `_modify_observation_callback`):
  37 entries. Ours is the same: positions, velocities, then ("cmd_cos", "cmd_sin", "cmd_speed") with
  the speed fixed at 0.5 m/s. (LocoMuJoCo also adds a visual direction-arrow body; we do not.)
* Reward "velocity_vector": exp(-5 ||v_xy - 0.5 (cos t, sin t)||). Tasks: simple (walk straight,
  t = 0) and hard (8 directions in its dataset; here a uniformly random direction per episode).
* `_has_fallen` (unitreeA1.py lines 520-522): trunk_list outside [-0.2793, 0.2793], trunk_tilt outside
  [-0.192, 0.192], trunk_tz < -0.24 (no upper bound, no yaw bound). The trunk body sits at z = 0.43,
  so the height band is [0.19, inf) m on the trunk world z.
* The model file's timestep is 0.002; LocoMuJoCo (and we) simulate at 0.001.

Start pose ("stand" keyframe, ours): qpos0 has straight legs with the calf joints at 0, outside their
range [-2.697, -0.916]; we crouch every leg to thigh 0.8, calf -1.6 rad (hip 0) and lower trunk_tz by
0.1313 m so the four feet touch the floor (measured with `mujoco.mj_geomDistance`): trunk at 0.299 m.
With zero torque the legs fold and the height bound ends the episode after 0.34 s.
"""
from __future__ import annotations

import numpy as np

from loco_il.environments.bodies.locomujoco.common import (HORIZON, STAND_KEY, RootJointFall, add_keyframe,
                                                           locomujoco_body, slide_to_height)
from loco_il.environments.registry import register_body
from loco_il.environments.tasks import (DirectionalVelocityReward, Task, random_direction_command,
                                        straight_command)

MODEL = "quadrupeds/unitree_a1_torque.xml"
TRUNK_Z = 0.43      # unitree_a1_torque.xml: <body name="trunk" pos="0 0 0.43">
GOAL_SPEED = 0.5    # LocoMuJoCo UnitreeA1(default_target_velocity=0.5)
COMMAND_NAMES = ("cmd_cos", "cmd_sin", "cmd_speed")
#: start-state noise: uniform +-0.01 on every qpos and qvel entry, the humanoids' scale (common.py), so that seeded
#: evaluation episodes start from distinct states; the built-in trot controller keeps its return with it
#: (751.1 over 10 episodes, against 748.8 without)
RESET_NOISE = ("uniform", 0.01)

TERMINATION = RootJointFall(
    height_range=slide_to_height(TRUNK_Z, (-0.24, np.inf)),
    joint_bounds=(("trunk_list", -0.2793, 0.2793),
                  ("trunk_tilt", -0.192, 0.192)))


def command_features(command: np.ndarray) -> np.ndarray:
    """(cos t, sin t, goal speed): LocoMuJoCo's last three UnitreeA1 observation entries."""
    return np.array([np.cos(command[0]), np.sin(command[0]), GOAL_SPEED])


TASKS = {
    "simple": Task(DirectionalVelocityReward(GOAL_SPEED, 5.0), TERMINATION, horizon=HORIZON,
                   command_sampler=straight_command, command_features=command_features,
                   command_names=COMMAND_NAMES,
                   description="UnitreeA1: walk straight (+x) at 0.5 m/s (LocoMuJoCo simple)"),
    "hard": Task(DirectionalVelocityReward(GOAL_SPEED, 5.0), TERMINATION, horizon=HORIZON,
                 command_sampler=random_direction_command, command_features=command_features,
                 command_names=COMMAND_NAMES,
                 description="UnitreeA1: walk at 0.5 m/s in a random direction drawn per episode (LocoMuJoCo hard)"),
}

STAND_POSE = {"trunk_tz": -0.1313,
              **{f"{leg}_{part}_joint": angle for leg in ("FR", "FL", "RR", "RL")
                 for part, angle in (("thigh", 0.8), ("calf", -1.6))}}


def _edit(spec) -> None:
    add_keyframe(spec, STAND_POSE, STAND_KEY)


UNITREE_A1 = locomujoco_body("UnitreeA1", MODEL, TASKS, "locomujoco/quadrupeds", _edit,
                             family="quadruped", default_task="simple", reset_noise=RESET_NOISE)

register_body(UNITREE_A1)
