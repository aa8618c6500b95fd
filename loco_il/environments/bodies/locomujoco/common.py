"""Shared parts of LocoMuJoCo 0.4.1's own robots (Atlas, Talos, Unitree H1/G1/A1, torque/muscle humanoid).

Facts (LocoMuJoCo 0.4.1, `loco_mujoco/environments/base.py`, `LocoEnv.__init__` defaults): physics
timestep 0.001 s, 10 substeps per action (100 Hz control), horizon 1000, gamma 0.99. The models have
no free joint: the root is six joints on the root body (three slides, then three hinges).

Termination. LocoMuJoCo's `_has_fallen` bounds the vertical root slide joint (pelvis_ty / trunk_tz, a
displacement from the root body's model position) and the root hinge angles (tilt/list/rotation), plus
back/lumbar joints where present. Our robots keep exactly these root joints, so `RootJointFall` bounds
the same hinge angles by joint name (asymmetric bounds, and the yaw bound LocoMuJoCo uses, cannot be
expressed as a symmetric roll/pitch limit); the slide bound is translated to the root body's world
height: z_world = z_model + q_slide (the slides act before the hinges, along world axes), i.e.
(lo, hi) on q_slide becomes (z_model + lo, z_model + hi) on z. A state is healthy when every value lies
in its closed interval (LocoMuJoCo: fallen if q < lo or q > hi).

Start state. LocoMuJoCo starts from dataset states; the models have no keyframe. Each body adds a
"stand" keyframe (feet on the floor, measured with `mujoco.mj_geomDistance`), see `add_keyframe`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import Any, Callable, Mapping, Sequence

import mujoco
import numpy as np

from loco_il.environments.assets import LICENCES, locomujoco_asset
from loco_il.environments.body import Body
from loco_il.environments.tasks import EpisodeDraw, StepContext, Task, TargetVelocityReward

TIMESTEP = 0.001        # LocoMuJoCo LocoEnv(timestep=0.001)
CONTROL_DT = 0.01       # LocoMuJoCo LocoEnv(n_substeps=10) -> 100 Hz
HORIZON = 1000          # LocoMuJoCo LocoEnv(horizon=1000)
WALK_SPEED = 1.25       # m/s, LocoMuJoCo reward_params target_velocity for walk (and carry)
RUN_SPEED = 2.5         # m/s, LocoMuJoCo reward_params target_velocity for run
DATASETS = ("real", "perfect", "preference")
STAND_KEY = "stand"
#: start-state noise of the humanoids: uniform +-0.01 on every qpos and qvel entry (rad, m, rad/s, m/s), the
#: scale of Gymnasium's Humanoid-v5 (reset_noise_scale 1e-2), so that seeded episodes start from distinct states
#: (LocoMuJoCo itself starts from dataset states; ours start standing)
HUMANOID_RESET_NOISE = ("uniform", 0.01)


def loader(relative: str) -> Callable[[], mujoco.MjSpec]:
    """A `load_spec` for one LocoMuJoCo model file (fetched into the asset cache on first use)."""
    def load() -> mujoco.MjSpec:
        return mujoco.MjSpec.from_file(str(locomujoco_asset(relative)))
    load.__qualname__ = f"load_locomujoco[{relative}]"
    return load


@dataclass(frozen=True)
class RootJointFall:
    """LocoMuJoCo's `_has_fallen`: root-body height band plus closed bounds on named joint angles.

    height_range: (lo, hi) on the world z of the root body (the body of the model's first joint), metres.
    joint_bounds: ((joint_name, lo, hi), ...) on joint positions (radians), e.g. pelvis tilt/list/rotation.
    slide_relative: height_range bounds the root's displacement from its model height (LocoMuJoCo's
        vertical slide itself) instead of its world z: for models drawn in several sizes (4Ages).
    """

    height_range: tuple[float, float]
    joint_bounds: tuple[tuple[str, float, float], ...] = ()
    slide_relative: bool = False
    _layout: dict = field(default_factory=dict, compare=False, repr=False)   # id(model) -> (qpos idx, lo, hi)

    def _bounds(self, model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """qpos addresses and bounds of the named joints, looked up once per compiled model, not per step."""
        key = id(model)
        if key not in self._layout:
            idx = []
            for name, _, _ in self.joint_bounds:
                jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
                if jid < 0:
                    raise KeyError(f"termination bounds joint {name!r}, which this model does not have")
                idx.append(model.jnt_qposadr[jid])
            self._layout.clear()       # one live model per env: keep only the current one
            self._layout[key] = (np.array(idx, dtype=np.intp), np.array([b[1] for b in self.joint_bounds]),
                                 np.array([b[2] for b in self.joint_bounds]))
        return self._layout[key]

    def __call__(self, ctx: StepContext) -> bool:
        model, data = ctx.model, ctx.data
        root = model.jnt_bodyid[0]
        z = data.xpos[root, 2] - (model.body_pos[root, 2] if self.slide_relative else 0.0)
        if not self.height_range[0] <= z <= self.height_range[1]:
            return True
        idx, lo, hi = self._bounds(model)
        q = data.qpos[idx]
        return bool(((q < lo) | (q > hi)).any())


def slide_to_height(z_model: float, slide_range: tuple[float, float]) -> tuple[float, float]:
    """Translate LocoMuJoCo's bound on the vertical root slide into a world-height band of the root body."""
    return (z_model + slide_range[0], z_model + slide_range[1])


def add_keyframe(spec: mujoco.MjSpec, pose: Mapping[str, float], name: str = STAND_KEY) -> None:
    """Add a keyframe whose qpos is each joint's `ref` (its qpos0) except the joints named in `pose`."""
    known = {j.name for j in spec.joints}
    unknown = set(pose) - known
    if unknown:
        raise KeyError(f"start pose names joints the model lacks: {sorted(unknown)}")
    qpos = []
    for joint in spec.joints:
        if joint.type not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            raise TypeError(f"add_keyframe handles hinge/slide joints only; {joint.name!r} is {joint.type}")
        qpos.append(float(pose.get(joint.name, joint.ref)))
    spec.add_key(name=name, qpos=qpos)


def set_body_quats(spec: mujoco.MjSpec, quats: Mapping[str, Sequence[float]]) -> None:
    """Set body orientations (MuJoCo normalizes the quaternions when compiling)."""
    for body_name, quat in quats.items():
        body = spec.body(body_name)
        if body is None:
            raise KeyError(f"the model has no body {body_name!r}")
        body.quat = np.asarray(quat, dtype=float)


def pelvis_bounds(rotation: float) -> tuple[tuple[str, float, float], ...]:
    """The pelvis tilt/list bounds every LocoMuJoCo humanoid shares, plus its own yaw (rotation) bound."""
    return (("pelvis_tilt", -np.pi / 4.5, np.pi / 12),
            ("pelvis_list", -np.pi / 12, np.pi / 8),
            ("pelvis_rotation", -rotation, rotation))


def locomujoco_body(name: str, model: str, tasks: Mapping[str, Task], licence_key: str,
                    spec_edit: Callable[[mujoco.MjSpec], None], **fields: Any) -> Body:
    """A `Body` with the settings all LocoMuJoCo robots share (timestep, 100 Hz control, datasets,
    the "stand" keyframe); `fields` sets the rest (family, default_task, removed joints, ...)."""
    fields.setdefault("family", "humanoid")
    fields.setdefault("default_task", "walk")
    if fields["family"] == "humanoid":
        fields.setdefault("reset_noise", HUMANOID_RESET_NOISE)
    return Body(name=name, load_spec=loader(model), tasks=tasks, datasets=DATASETS, default_dataset="real",
                control_dt=CONTROL_DT, timestep=TIMESTEP, init_keyframe=STAND_KEY,
                licence=LICENCES[licence_key], source=f"loco-mujoco 0.4.1 environments/data/{model}",
                spec_edit=spec_edit, pomdp_hide=("velocities",), **fields)


def humanoid_tasks(termination: RootJointFall, run: bool, robot: str) -> dict[str, Task]:
    """walk (1.25 m/s), optionally run (2.5 m/s), and stand (0 m/s), all with the same fall termination."""
    tasks = {"walk": Task(TargetVelocityReward(WALK_SPEED), termination, horizon=HORIZON,
                          description=f"{robot}: walk forward at {WALK_SPEED} m/s (LocoMuJoCo walk)")}
    if run:
        tasks["run"] = Task(TargetVelocityReward(RUN_SPEED), termination, horizon=HORIZON,
                            description=f"{robot}: run forward at {RUN_SPEED} m/s (LocoMuJoCo run)")
    tasks["stand"] = Task(TargetVelocityReward(0.0), termination, horizon=HORIZON,
                          description=f"{robot}: stand still (target velocity 0; not in LocoMuJoCo)")
    return tasks


# ---------------------------------------------------------------- carry
#: the carried masses (kg) drawn per episode: `_valid_weights` of LocoMuJoCo's Atlas / Talos / UnitreeH1 `__init__`
CARRY_MASSES = (0.1, 1.0, 5.0, 10.0)
LOAD_BODY = "weight"    # LocoMuJoCo's name of the carried body (its observation reads this body's mass)


@dataclass(frozen=True)
class Load:
    """Where a robot carries its load (LocoMuJoCo's `_add_weight` of the robot's module): a box body on `parent`
    with half-sizes `half_size` at `pos` (parent frame), plus arm poses `body_quats` that hold it."""

    parent: str
    half_size: tuple[float, float, float]
    pos: tuple[float, float, float]
    body_quats: Mapping[str, Sequence[float]] = field(default_factory=dict)


def load_colour(mass: float) -> list[float]:
    """Blue for the lightest load to red for the heaviest (LocoMuJoCo `BaseRobotHumanoid._get_box_color`)."""
    t = CARRY_MASSES.index(mass) / (len(CARRY_MASSES) - 1) if mass in CARRY_MASSES else 1.0
    blue, red = np.array([0.2, 0.0, 1.0, 1.0]), np.array([1.0, 0.0, 0.0, 1.0])
    return list(blue + (red - blue) * t)


def add_load(spec: mujoco.MjSpec, mass: float, load: Load) -> None:
    """The load as a body of its own: a box with `mass` (uniform box inertia) welded to `load.parent`."""
    parent = spec.body(load.parent)
    if parent is None:
        raise KeyError(f"the load's parent body {load.parent!r} is not in the model")
    if mass <= 0:
        raise ValueError(f"a carried mass must be positive, got {mass}")
    hx, hy, hz = load.half_size
    inertia = [mass / 3 * (hy ** 2 + hz ** 2), mass / 3 * (hx ** 2 + hz ** 2), mass / 3 * (hx ** 2 + hy ** 2)]
    body = parent.add_body(name=LOAD_BODY, pos=list(load.pos), mass=mass, inertia=inertia, explicitinertial=True)
    body.add_geom(name=LOAD_BODY, type=mujoco.mjtGeom.mjGEOM_BOX, size=list(load.half_size), mass=mass,
                  rgba=load_colour(mass))
    set_body_quats(spec, load.body_quats)


def carried_mass(mass: float) -> np.ndarray:
    return np.array([mass])


def carry_task(termination: RootJointFall, robot: str, load: Load) -> Task:
    """LocoMuJoCo's carry: walk at 1.25 m/s carrying a load whose mass is drawn per episode from
    `CARRY_MASSES`; the observation gains the mass (group "weight", as LocoMuJoCo's `get_mask` names it)."""
    draw = EpisodeDraw(values=CARRY_MASSES, edit=partial(_edit_load, load=load), names=("carried_mass",),
                       group="weight", features=carried_mass)
    return Task(TargetVelocityReward(WALK_SPEED), termination, horizon=HORIZON, draw=draw,
                description=f"{robot}: walk forward at {WALK_SPEED} m/s carrying a load of "
                            f"{', '.join(map(str, CARRY_MASSES))} kg drawn per episode (LocoMuJoCo carry)")


def _edit_load(spec: mujoco.MjSpec, mass: float, load: Load) -> None:
    add_load(spec, mass, load)
