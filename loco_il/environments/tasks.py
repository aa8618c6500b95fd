"""Tasks: reward terms, termination rules and command features.

Rewards are for evaluation in imitation learning; users may pass any callable with the
`RewardFn` signature (`env = LocoEnv.make(id, reward=my_fn)`).

Two families:
* LocoMuJoCo-style velocity tracking for robots (facts from LocoMuJoCo 0.4.1:
  r = exp(-(v_x - v*)^2), v* = 1.25 m/s walk, 2.5 m/s run; quadrupeds
  r = exp(-5 ||v_xy - 0.5 (cos t, sin t)||)), with fall terminations on root height and orientation.
* Gymnasium MuJoCo v5 rewards and terminations for the classic bodies, with the v5 default weights
  (Gymnasium's documentation of Hopper/Walker2d/HalfCheetah/Ant/Humanoid/HumanoidStandup-v5),
  so returns compare with the literature.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Mapping, Protocol, Sequence

import mujoco
import numpy as np


@dataclass(slots=True)
class StepContext:
    """What a reward or termination may look at after one env step."""

    model: mujoco.MjModel
    data: mujoco.MjData
    dt: float
    action: np.ndarray          # normalized action in [-1, 1]
    xy_before: np.ndarray        # reference point (root body or centre of mass) before the step
    xy_after: np.ndarray
    command: np.ndarray          # task command (e.g. direction angle), empty if none
    healthy: bool = True

    @property
    def xy_velocity(self) -> np.ndarray:
        return (self.xy_after - self.xy_before) / self.dt


class RewardFn(Protocol):
    def __call__(self, ctx: StepContext) -> tuple[float, dict[str, float]]: ...


class TerminationFn(Protocol):
    def __call__(self, ctx: StepContext) -> bool: ...


# ---------------------------------------------------------------- rewards
@dataclass(frozen=True)
class TargetVelocityReward:
    """exp(-(v_x - target)^2): LocoMuJoCo's humanoid walk/run reward, in (0, 1] per step."""

    target: float

    def __call__(self, ctx: StepContext) -> tuple[float, dict[str, float]]:
        vx = float(ctx.xy_velocity[0])
        return float(np.exp(-(vx - self.target) ** 2)), {"x_velocity": vx}


@dataclass(frozen=True)
class ScaledTargetVelocityReward:
    """exp(-(v_x - target * s)^2) with s = the episode's drawn value (the body size of LocoMuJoCo's 4Ages
    humanoids: `MultiTargetVelocityReward` in loco_mujoco/utils/reward.py scales the target by the size)."""

    target: float

    def __call__(self, ctx: StepContext) -> tuple[float, dict[str, float]]:
        vx = float(ctx.xy_velocity[0])
        goal = self.target * float(ctx.command[0])
        return float(np.exp(-(vx - goal) ** 2)), {"x_velocity": vx, "target_velocity": goal}


@dataclass(frozen=True)
class DirectionalVelocityReward:
    """exp(-scale ||v_xy - speed (cos t, sin t)||): LocoMuJoCo's UnitreeA1 reward; t is the command angle."""

    speed: float = 0.5
    scale: float = 5.0

    def __call__(self, ctx: StepContext) -> tuple[float, dict[str, float]]:
        theta = float(ctx.command[0]) if ctx.command.size else 0.0
        goal = self.speed * np.array([np.cos(theta), np.sin(theta)])
        err = float(np.linalg.norm(ctx.xy_velocity - goal))
        return float(np.exp(-self.scale * err)), {"velocity_error": err}


@dataclass(frozen=True)
class GymLocomotionReward:
    """Gymnasium v5: forward_weight * v_x + healthy_reward * healthy - ctrl_cost * |ctrl|^2 - contact cost.

    `contact_force_clip` clips each cfrc_ext entry first (Ant v5); `contact_cost_max` clips the cost (Humanoid v5).
    """

    forward_weight: float = 1.0
    ctrl_cost_weight: float = 1e-3
    healthy_reward: float = 1.0
    contact_cost_weight: float = 0.0
    contact_force_clip: tuple[float, float] | None = None
    contact_cost_max: float = np.inf

    def __call__(self, ctx: StepContext) -> tuple[float, dict[str, float]]:
        vx = float(ctx.xy_after[0] - ctx.xy_before[0]) / ctx.dt
        forward = self.forward_weight * vx
        healthy = self.healthy_reward * float(ctx.healthy)
        ctrl_vec = ctx.data.ctrl
        ctrl = self.ctrl_cost_weight * float(ctrl_vec @ ctrl_vec)
        contact = 0.0
        if self.contact_cost_weight:
            forces = ctx.data.cfrc_ext.ravel()
            if self.contact_force_clip is not None:
                forces = forces.clip(*self.contact_force_clip)
            contact = min(self.contact_cost_weight * float(forces @ forces), self.contact_cost_max)
        terms = {"forward": forward, "healthy": healthy, "ctrl_cost": -ctrl, "contact_cost": -contact,
                 "x_velocity": vx}
        return forward + healthy - ctrl - contact, terms


@dataclass(frozen=True)
class StandupReward:
    """HumanoidStandup v5: z / timestep - 0.1 |ctrl|^2 - min(0.5e-6 |cfrc_ext|^2, 10) + 1."""

    ctrl_cost_weight: float = 0.1
    impact_cost_weight: float = 0.5e-6
    impact_cost_max: float = 10.0

    def __call__(self, ctx: StepContext) -> tuple[float, dict[str, float]]:
        up = float(ctx.data.qpos[2]) / ctx.model.opt.timestep
        ctrl = self.ctrl_cost_weight * float(np.square(ctx.data.ctrl).sum())
        impact = min(self.impact_cost_weight * float(np.square(ctx.data.cfrc_ext).sum()), self.impact_cost_max)
        return up - ctrl - impact + 1.0, {"linup": up, "ctrl_cost": -ctrl, "impact_cost": -impact}


@dataclass(frozen=True)
class AliveReward:
    """1 per step while healthy (InvertedPendulum v5)."""

    def __call__(self, ctx: StepContext) -> tuple[float, dict[str, float]]:
        return float(ctx.healthy), {}


# ---------------------------------------------------------------- terminations
@dataclass(frozen=True)
class PlanarHealthy:
    """Hopper/Walker2d v5: z = qpos[1] and angle = qpos[2] inside open ranges; optionally |state[2:]| < 100."""

    z_range: tuple[float, float]
    angle_range: tuple[float, float]
    state_range: tuple[float, float] | None = None

    def __call__(self, ctx: StepContext) -> bool:
        z, angle = ctx.data.qpos[1], ctx.data.qpos[2]
        ok = self.z_range[0] < z < self.z_range[1] and self.angle_range[0] < angle < self.angle_range[1]
        if ok and self.state_range is not None:
            state = np.concatenate([ctx.data.qpos, ctx.data.qvel])[2:]
            ok = bool(np.all((self.state_range[0] < state) & (state < self.state_range[1])))
        return not ok


@dataclass(frozen=True)
class HeightHealthy:
    """Ant/Humanoid v5: root height qpos[2] inside the range (inclusive for Ant, open for Humanoid)."""

    z_range: tuple[float, float]
    inclusive: bool = False

    def __call__(self, ctx: StepContext) -> bool:
        # (Gymnasium also requires a finite state; LocoEnv ends diverged, non-finite episodes before this)
        z = ctx.data.qpos[2]
        lo, hi = self.z_range
        ok = lo <= z <= hi if self.inclusive else lo < z < hi
        return not ok


@dataclass(frozen=True)
class PoleFallen:
    """InvertedPendulum v5: |pole angle| > limit."""

    limit: float = 0.2

    def __call__(self, ctx: StepContext) -> bool:
        return bool(abs(ctx.data.qpos[1]) > self.limit)


@dataclass(frozen=True)
class FallTermination:
    """A robot has fallen when its root body leaves a height band or tilts too far.

    Height is the root body's world z (metres); roll and pitch come from the root body's
    world orientation (radians, about world x and y after removing heading). Per-robot bounds
    are documented in each robot module.
    """

    height_range: tuple[float, float]
    max_roll: float = np.pi / 4
    max_pitch: float = np.pi / 4
    root_body: int = 1

    def __call__(self, ctx: StepContext) -> bool:
        z = ctx.data.xpos[self.root_body, 2]
        if not self.height_range[0] < z < self.height_range[1]:
            return True
        # body z-axis in world: its tilt tells roll and pitch regardless of heading
        R = ctx.data.xmat[self.root_body].reshape(3, 3)
        heading = np.arctan2(R[1, 0], R[0, 0])
        c, s = np.cos(heading), np.sin(heading)
        up = R[:, 2]
        local_x = c * up[0] + s * up[1]        # tilt forward/back in the heading frame
        local_y = -s * up[0] + c * up[1]       # tilt sideways
        pitch = np.arctan2(local_x, up[2])
        roll = np.arctan2(-local_y, up[2])
        return bool(abs(roll) > self.max_roll or abs(pitch) > self.max_pitch)


# ---------------------------------------------------------------- task
StateMap = Callable[[mujoco.MjModel, np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class EpisodeDraw:
    """A few physical versions of the model, one drawn per episode and shown to the policy.

    LocoMuJoCo builds one model per version and picks one at every reset (`LocoEnv.reset`,
    loco_mujoco/environments/base.py): the carried mass of `carry`, the body size of the 4Ages humanoids.
    The env's command is the drawn value (rewards read it), the observation gains `features(value)`.

    values: the versions (e.g. masses in kg, body scales); `edit(spec, value)` builds a version from the
        body's spec; versions must keep the joints and actuators (the layout is shared).
    names / group: the observation entries of `features` and their group (POMDP masks hide groups).
    modes: Task-ID mode -> indices of the values drawn from (empty: the task has no mode part);
        `default_mode` fills a missing mode.
    reference: index of the version that motion is retargeted to (datasets); `state_map(model, qpos, qvel,
        value)` carries a state of the reference version to the version `value` (None: unchanged).
    """

    values: tuple[float, ...]
    edit: Callable[[mujoco.MjSpec, float], None]
    names: tuple[str, ...]
    group: str
    features: Callable[[float], np.ndarray]
    modes: Mapping[str, tuple[int, ...]] = field(default_factory=dict)
    default_mode: str | None = None
    reference: int = 0
    state_map: StateMap | None = None

    def indices(self, mode: str | None) -> tuple[int, ...]:
        """Indices of the values a mode draws from (every value when the task has no modes)."""
        if not self.modes:
            return tuple(range(len(self.values)))
        return self.modes[mode if mode is not None else self.default_mode]


@dataclass(frozen=True)
class Task:
    """A task of one body: its reward, termination, horizon and command features.

    `velocity_point`: where v_xy is measured: "root" (root body position, Gymnasium's Hopper/Ant and
    LocoMuJoCo's pelvis), "com" (mass centre, Gymnasium's Humanoid), or a body name.
    `command_sampler(rng) -> np.ndarray` draws a command per episode (e.g. walking direction);
    `command_features(command) -> np.ndarray` is appended to the observation, named `command_names`.
    `resample_command_every`: steps between command redraws (0 = once per episode).
    `command_group`: observation group of the command entries.
    `draw`: physical versions of the model drawn per episode (`EpisodeDraw`); the command is then the drawn
    value and the observation entries are the draw's (no `command_sampler`).
    """

    reward: RewardFn
    termination: TerminationFn | None = None
    horizon: int = 1000
    velocity_point: str = "root"
    needs_contact_forces: bool = False
    command_sampler: Callable[[np.random.Generator], np.ndarray] | None = None
    command_features: Callable[[np.ndarray], np.ndarray] | None = None
    command_names: Sequence[str] = field(default_factory=tuple)
    resample_command_every: int = 0
    description: str = ""
    command_group: str = "command"
    draw: EpisodeDraw | None = None

    def __post_init__(self) -> None:
        if self.draw is not None and (self.command_sampler is not None or self.command_features is not None):
            raise ValueError("a task with a draw takes its command and features from the draw; "
                             "drop command_sampler / command_features")


def straight_command(rng: np.random.Generator) -> np.ndarray:
    return np.zeros(1)


def random_direction_command(rng: np.random.Generator) -> np.ndarray:
    return np.array([rng.uniform(-np.pi, np.pi)])


def direction_features(command: np.ndarray) -> np.ndarray:
    return np.array([np.cos(command[0]), np.sin(command[0])])
