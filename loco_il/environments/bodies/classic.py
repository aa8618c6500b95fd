"""Gymnasium's MuJoCo bodies with their v5 rewards, terminations, frame skips and start noise.

Weights and ranges are Gymnasium v5's documented defaults (Gymnasium 1.x `*_v5.py`), so that
returns compare with published numbers. Observations follow loco_il's convention (joint positions
without the horizontal root coordinates, then all joint velocities; no cinert/cvel/cfrc terms).
"""
from __future__ import annotations

import warnings

import mujoco

from loco_il.environments.assets import LICENCES, gymnasium_asset
from loco_il.environments.body import Body
from loco_il.environments.registry import register_body
from loco_il.environments.tasks import (AliveReward, GymLocomotionReward, HeightHealthy, PlanarHealthy, PoleFallen,
                                        StandupReward, Task)


def _gym_loader(filename: str):
    def load() -> mujoco.MjSpec:
        with warnings.catch_warnings():  # Gymnasium's humanoid.xml uses the deprecated `settotalmass`
            warnings.filterwarnings("ignore", message=".*settotalmass.*")
            return mujoco.MjSpec.from_file(str(gymnasium_asset(filename)))
    return load


def _classic(name: str, xml: str, frame_skip: int, tasks: dict[str, Task], noise: tuple[str, float],
             default_task: str = "run", exclude_root_xy: bool = True) -> Body:
    # Gymnasium's xml timesteps: 0.002 (Hopper/Walker), 0.01 (HalfCheetah/Ant), 0.003 (Humanoid), 0.02 (pendulum)
    timestep = _gym_loader(xml)().option.timestep
    return Body(name=name, load_spec=_gym_loader(xml), tasks=tasks, default_task=default_task,
                datasets=("perfect", "preference"), default_dataset="perfect", family="classic",
                control_dt=frame_skip * timestep, reset_noise=noise, licence=LICENCES["gymnasium"],
                source=f"gymnasium/envs/mujoco/assets/{xml}", exclude_root_xy=exclude_root_xy)


CLASSIC_BODIES = [
    _classic("Hopper", "hopper.xml", 4, {"run": Task(
        GymLocomotionReward(1.0, 1e-3, 1.0),
        PlanarHealthy((0.7, float("inf")), (-0.2, 0.2), (-100.0, 100.0)),
        description="Gymnasium Hopper-v5")}, ("uniform", 5e-3)),
    _classic("Walker2d", "walker2d_v5.xml", 4, {"run": Task(
        GymLocomotionReward(1.0, 1e-3, 1.0), PlanarHealthy((0.8, 2.0), (-1.0, 1.0)),
        description="Gymnasium Walker2d-v5")}, ("uniform", 5e-3)),
    _classic("HalfCheetah", "half_cheetah.xml", 5, {"run": Task(
        GymLocomotionReward(1.0, 0.1, 0.0), description="Gymnasium HalfCheetah-v5")}, ("uniform_normal", 0.1)),
    _classic("Ant", "ant.xml", 5, {"run": Task(
        GymLocomotionReward(1.0, 0.5, 1.0, contact_cost_weight=5e-4, contact_force_clip=(-1.0, 1.0)),
        HeightHealthy((0.2, 1.0), inclusive=True), needs_contact_forces=True,
        velocity_point="torso", description="Gymnasium Ant-v5")}, ("uniform_normal", 0.1)),
    _classic("Humanoid", "humanoid.xml", 5, {"run": Task(
        GymLocomotionReward(1.25, 0.1, 5.0, contact_cost_weight=5e-7, contact_cost_max=10.0),
        HeightHealthy((1.0, 2.0)), needs_contact_forces=True, velocity_point="com",
        description="Gymnasium Humanoid-v5")}, ("uniform", 1e-2)),
    _classic("HumanoidStandup", "humanoidstandup.xml", 5, {"standup": Task(
        StandupReward(), needs_contact_forces=True, description="Gymnasium HumanoidStandup-v5")},
        ("uniform", 1e-2), default_task="standup"),
    # a cheap body for algorithm learning tests (Gymnasium InvertedPendulum-v5)
    _classic("InvertedPendulum", "inverted_pendulum.xml", 2, {"balance": Task(
        AliveReward(), PoleFallen(0.2), description="Gymnasium InvertedPendulum-v5")},
        ("uniform", 1e-2), default_task="balance", exclude_root_xy=False),
]

for _body in CLASSIC_BODIES:
    register_body(_body)
