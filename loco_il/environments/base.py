"""`LocoEnv`: the one stepping loop shared by every body and task.

It is a mushroom-rl `Environment` (reset -> obs; step -> obs, reward, absorbing, info); the
Gymnasium interface is a thin adapter around it (`gym_adapter.py`).

Safe behaviour on bad input (documented in the README):
* wrong action shape or a NaN/inf action raises `ValueError`; finite actions outside [-1, 1] are clipped;
* a simulation that diverges (MuJoCo's bad-qacc warning, non-finite state) ends the episode with a
  terminal transition: `absorbing=True`, reward 0, the last finite observation and
  `info["diverged"] = True`; stepping again before `reset()` raises `RuntimeError`.
"""
from __future__ import annotations

import math
import warnings
from typing import Any, Callable, Sequence

import mujoco
import numpy as np
from mushroom_rl.core import Environment, MDPInfo
from mushroom_rl.utils.spaces import Box

from loco_il.environments.body import Body
from loco_il.environments.observations import ObservationSpec, joint_layout, observation_spec, root_xy_projection
from loco_il.environments.tasks import RewardFn, StepContext, Task

# MuJoCo checks qpos/qvel/qacc every step (non-finite or huge), warns and resets the data: a warning
# count that moved during our substeps means the simulation diverged
_DIVERGENCE_WARNINGS = (int(mujoco.mjtWarning.mjWARN_BADQPOS), int(mujoco.mjtWarning.mjWARN_BADQVEL),
                        int(mujoco.mjtWarning.mjWARN_BADQACC))

InitStateSampler = Callable[[np.random.Generator], tuple[np.ndarray, np.ndarray]]


def action_map(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """(centre, half-width) of each actuator's control range: an action a in [-1, 1] drives
    ctrl = centre + a * half-width (an unlimited actuator takes [-1, 1] as its range)."""
    limited = model.actuator_ctrllimited.astype(bool)
    lo = np.where(limited, model.actuator_ctrlrange[:, 0], -1.0)
    hi = np.where(limited, model.actuator_ctrlrange[:, 1], 1.0)
    return (hi + lo) / 2, (hi - lo) / 2


def name_unnamed_joints(spec: mujoco.MjSpec) -> None:
    """Give every unnamed joint a stable name (`<body>_root` for a free joint) so poses and
    observation entries can refer to it (Menagerie robots leave their free root joint unnamed)."""
    for i, joint in enumerate(spec.joints):
        if not joint.name:
            owner = joint.parent.name or f"body{i}"
            joint.name = f"{owner}_root" if joint.type == mujoco.mjtJoint.mjJNT_FREE else f"{owner}_joint{i}"


def keyframe_pose(spec: mujoco.MjSpec, key_name: str | None) -> dict[str, np.ndarray]:
    """A keyframe's qpos split by joint name, read from the spec (survives joint removal)."""
    keys = list(spec.keys)
    key = next((k for k in keys if k.name == key_name), None) if key_name else None
    if key is None:
        return {}
    sizes = {mujoco.mjtJoint.mjJNT_FREE: 7, mujoco.mjtJoint.mjJNT_BALL: 4}
    pose, adr = {}, 0
    qpos = np.asarray(key.qpos)
    for joint in spec.joints:
        n = sizes.get(joint.type, 1)
        if adr + n <= qpos.size:
            pose[joint.name] = qpos[adr:adr + n].copy()
        adr += n
    return pose


def remove_elements(spec: mujoco.MjSpec, joints: Sequence[str], actuators: Sequence[str]) -> None:
    """Delete joints (welding their bodies to the parent) and actuators, plus everything that refers to them."""
    joints, actuators = set(joints), set(actuators)
    for act in list(spec.actuators):
        if act.name in actuators or act.target in joints:
            spec.delete(act)
    for sensor in list(spec.sensors):
        if sensor.objname in joints or sensor.objname in actuators:
            spec.delete(sensor)
    for eq in list(spec.equalities):
        if eq.name1 in joints or eq.name2 in joints:
            spec.delete(eq)
    for name in joints:
        joint = spec.joint(name)
        if joint is None:
            raise KeyError(f"cannot remove joint {name!r}: the model has no such joint")
        spec.delete(joint)
    for key in list(spec.keys):   # keyframes no longer match the qpos size; poses are kept by name
        spec.delete(key)


def _compile_spec(spec: mujoco.MjSpec) -> mujoco.MjModel:
    with warnings.catch_warnings():  # Gymnasium's humanoid.xml uses the deprecated `settotalmass`
        warnings.filterwarnings("ignore", message=".*settotalmass.*")
        return spec.compile()


class LocoEnv(Environment):
    """A locomotion MDP for one body and task. Create it from a Task-ID with `LocoEnv.make`."""

    def __init__(self, body: Body, task: str, dataset_type: str, *, variant: str | None = None,
                 mode: str | None = None, pomdp: bool = False, hide: Sequence[str] = (),
                 reward: RewardFn | None = None,
                 randomization: Any = None, randomize_every: int = 1, seed: int | None = None,
                 render_mode: str | None = None, horizon: int | None = None,
                 init_state_sampler: InitStateSampler | None = None,
                 render_size: tuple[int, int] = (480, 640)):
        self.body = body
        self.body_name = body.name
        self.task_name = task
        self.dataset_type = dataset_type
        self.variant = variant
        self.pomdp = pomdp
        self.task: Task = body.tasks[task]
        self.reward_fn: RewardFn = reward if reward is not None else self.task.reward
        self.render_mode = render_mode
        self.render_size = render_size
        self.init_state_sampler = init_state_sampler
        self._rng = np.random.default_rng(seed)
        self._seed = seed
        self.draw = self.task.draw
        self.mode = self._check_mode(mode)
        self._draw_indices = self.draw.indices(self.mode) if self.draw is not None else ()
        self._draw_models: dict[int, mujoco.MjModel] = {}   # drawn version -> its compiled model
        self._command = np.zeros(0)

        self.base_spec = self._build_spec()
        self.randomization = randomization
        self.randomize_every = max(1, int(randomize_every))
        self._episodes = 0
        if self.draw is not None:   # until the first reset: the reference version if the mode draws it
            ref = self.draw.reference
            self.select_draw(ref if ref in self._draw_indices else self._draw_indices[0])
        else:
            self._compile(self.base_spec)

        layout = self._layout
        command_names = tuple(self.draw.names if self.draw is not None else self.task.command_names)
        group = self.draw.group if self.draw is not None else self.task.command_group
        self.full_obs_spec: ObservationSpec = observation_spec(layout, command_names, group)
        hide_groups = tuple(body.pomdp_hide) if pomdp else ()
        hidden_names = tuple(h for h in hide if h not in set(self.full_obs_spec.groups))
        hidden_groups = hide_groups + tuple(h for h in hide if h in set(self.full_obs_spec.groups))
        self.obs_mask = self.full_obs_spec.mask(hidden_groups, hidden_names)
        self.obs_spec: ObservationSpec = self.full_obs_spec.masked(self.obs_mask)
        self._mask_all = bool(self.obs_mask.all())

        obs_dim = self.obs_spec.dim
        act_dim = self.model.nu
        horizon = horizon or self.task.horizon
        mdp_info = MDPInfo(Box(-np.inf * np.ones(obs_dim), np.inf * np.ones(obs_dim)),
                           Box(-np.ones(act_dim), np.ones(act_dim)), gamma=0.99, horizon=horizon,
                           dt=self.dt)
        super().__init__(mdp_info)
        self._steps = 0
        self._needs_reset = True
        self._last_obs = np.zeros(obs_dim)
        self._renderer = None
        self._viewer = None

    # ------------------------------------------------------------------ construction
    @classmethod
    def make(cls, task_id: str, **kwargs: Any) -> "LocoEnv":
        """Create an env from a Task-ID such as "UnitreeH1.walk.real" (missing parts take defaults)."""
        from loco_il.environments.registry import make
        return make(task_id, **kwargs)

    @staticmethod
    def get_all_task_names() -> list[str]:
        from loco_il.environments.registry import get_all_task_names
        return get_all_task_names()

    @property
    def task_id(self) -> str:
        body = self.body_name + (f"-{self.variant}" if self.variant else "")
        task = self.task_name + (f".{self.mode}" if self.mode else "")
        return f"{body}.{task}.{self.dataset_type}" + (".pomdp" if self.pomdp else "")

    def _check_mode(self, mode: str | None) -> str | None:
        modes = self.draw.modes if self.draw is not None else {}
        if not modes:
            if mode is not None:
                raise ValueError(f"{self.body_name}.{self.task_name} has no modes, got mode {mode!r}; drop it")
            return None
        if mode is None:
            return self.draw.default_mode
        if mode not in modes:
            raise ValueError(f"{self.body_name}.{self.task_name} has modes {', '.join(modes)}, not {mode!r}")
        return mode

    def _build_spec(self) -> mujoco.MjSpec:
        spec = self.body.load_spec()
        if self.body.spec_edit is not None:
            self.body.spec_edit(spec)
        name_unnamed_joints(spec)
        self._init_pose = keyframe_pose(spec, self.body.init_keyframe)
        if self.body.joints_to_remove or self.body.actuators_to_remove or self._init_pose:
            remove_elements(spec, self.body.joints_to_remove, self.body.actuators_to_remove)
        if self.body.timestep is not None:
            spec.option.timestep = self.body.timestep
        if self.variant:
            from loco_il.environments.variants import apply_variant
            apply_variant(spec, self.body_name, self.variant)
        return spec

    def _compile(self, spec: mujoco.MjSpec) -> None:
        """(Re)compile the model; everything derived from it (inertia, layout, ranges) follows."""
        self._adopt(_compile_spec(spec))

    def _version_spec(self, index: int) -> mujoco.MjSpec:
        """The spec of the drawn version `index` (a copy of the base spec with the draw's edit)."""
        spec = self.base_spec.copy()
        self.draw.edit(spec, self.draw.values[index])
        return spec

    def select_draw(self, index: int) -> None:
        """Use the drawn version `index` of the model (`reset` draws one itself; datasets pick each in turn).
        Versions are compiled once, on first use."""
        if self.draw is None:
            raise ValueError(f"{self.task_id} draws no model versions; select_draw applies to tasks with a draw")
        if not 0 <= index < len(self.draw.values):
            raise ValueError(f"draw index {index} out of range: {self.task_id} has {len(self.draw.values)} versions "
                             f"({', '.join(map(str, self.draw.values))})")
        self._drawn = int(index)
        self._command = np.array([self.draw.values[index]], dtype=np.float64)
        if index not in self._draw_models:
            self._draw_models[index] = _compile_spec(self._version_spec(index))
        self._adopt(self._draw_models[index])

    @property
    def draw_indices(self) -> tuple[int, ...]:
        """Indices of the draw's values this env's mode draws from (empty without a draw)."""
        return tuple(self._draw_indices)

    @property
    def drawn_index(self) -> int | None:
        """Index of the current version of the model among the draw's values (None without a draw)."""
        return self._drawn if self.draw is not None else None

    def _adopt(self, model: mujoco.MjModel) -> None:
        """Make `model` the env's model; everything derived from it (inertia, layout, ranges) follows."""
        self.model = model
        self.data = mujoco.MjData(self.model)
        self.n_substeps = max(1, int(round(self.body.control_dt / self.model.opt.timestep)))
        self.dt = self.n_substeps * self.model.opt.timestep
        self._layout = joint_layout(self.model, self.body.exclude_root_xy)
        self._ctrl_center, self._ctrl_half = action_map(self.model)
        self._init_qpos = self.model.qpos0.copy()
        for j in range(self.model.njnt):
            name = mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_JOINT, j)
            if name in self._init_pose:
                adr = self.model.jnt_qposadr[j]
                self._init_qpos[adr:adr + self._init_pose[name].size] = self._init_pose[name]
        if self.draw is not None and self.draw.state_map is not None:   # e.g. the start pose of a smaller body
            self._init_qpos, _ = self.draw.state_map(model, self._init_qpos, np.zeros(model.nv),
                                                     self.draw.values[self._drawn])
        self._root_body = int(self.model.jnt_bodyid[0]) if self.model.njnt else 1
        self._root_xy_idx, self._root_xy_proj = root_xy_projection(self.model)
        self._mass_fraction = self.model.body_mass / self.model.body_mass.sum()
        self._point_body = (mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, self.task.velocity_point)
                            if self.task.velocity_point not in ("root", "com") else self._root_body)
        if getattr(self, "_renderer", None) is not None:   # the renderer and viewer are bound to the old model
            self._renderer.close()
            self._renderer = None
        if getattr(self, "_viewer", None) is not None:
            self._viewer.close()
            self._viewer = None

    def randomize(self) -> None:
        """Draw new physical parameters: edit a copy of the base spec and recompile."""
        if self.randomization is None:
            raise RuntimeError("this env has no randomization config; pass randomization=... to make()")
        spec = self._version_spec(self._drawn) if self.draw is not None else self.base_spec.copy()
        self.randomization.apply(spec, self._rng)
        self._compile(spec)

    # ------------------------------------------------------------------ mushroom-rl interface
    def seed(self, seed: int | None) -> None:
        self._seed = seed
        self._rng = np.random.default_rng(seed)

    def reset(self, state: np.ndarray | None = None) -> np.ndarray:
        """Start an episode. `state`, if given, is a full simulator state (qpos, qvel) concatenated."""
        drawn = self._draw_index() if self.draw is not None else None
        due = self.randomization is not None and self._episodes % self.randomize_every == 0
        if self.randomization is not None and (due or drawn != self.drawn_index):
            if drawn is not None:   # a new version is randomized afresh
                self._drawn = drawn
            self.randomize()
        elif drawn is not None and drawn != self._drawn:
            self.select_draw(drawn)
        self._episodes += 1
        mujoco.mj_resetData(self.model, self.data)
        if state is not None:
            state = np.asarray(state, dtype=np.float64)
            if state.shape != (self.model.nq + self.model.nv,):
                raise ValueError(f"reset state must have shape ({self.model.nq + self.model.nv},) = (nq + nv); "
                                 f"got {state.shape}")
            qpos, qvel = state[:self.model.nq], state[self.model.nq:]
        elif self.init_state_sampler is not None:
            qpos, qvel = self.init_state_sampler(self._rng)
        else:
            qpos, qvel = self._noisy_init_state()
        self.data.qpos[:], self.data.qvel[:] = qpos, qvel
        if self.draw is not None:
            self._command = np.array([self.draw.values[self._drawn]], dtype=np.float64)
        else:
            self._command = (self.task.command_sampler(self._rng) if self.task.command_sampler
                             else np.zeros(0))
        mujoco.mj_forward(self.model, self.data)
        self._steps = 0
        self._needs_reset = False
        self._warnings0 = self._divergence_count()
        self._last_obs = self._observation()
        return self._last_obs.copy()

    def _draw_index(self) -> int:
        """This episode's version of the model: uniform over the mode's versions (LocoMuJoCo's random reset)."""
        idx = self._draw_indices
        return idx[int(self._rng.integers(len(idx)))] if len(idx) > 1 else idx[0]

    def _noisy_init_state(self) -> tuple[np.ndarray, np.ndarray]:
        kind, scale = self.body.reset_noise
        nq, nv = self.model.nq, self.model.nv
        qpos = self._init_qpos + self._rng.uniform(-scale, scale, nq)
        if kind == "uniform_normal":
            qvel = scale * self._rng.standard_normal(nv)
        else:
            qvel = self._rng.uniform(-scale, scale, nv)
        return qpos, qvel

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, dict]:
        if self._needs_reset:
            raise RuntimeError("step() called before reset() or after a diverged episode; call reset() first")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (self.model.nu,):
            raise ValueError(f"{self.task_id}: action must have shape ({self.model.nu},), got {np.shape(action)}")
        # element-wise: a sum would overflow for finite values near the float maximum (merely clipped below)
        if not np.isfinite(a).all():
            raise ValueError(f"{self.task_id}: action contains NaN or inf: {a}")
        a = a.clip(-1.0, 1.0)
        self.data.ctrl[:] = self._ctrl_center + a * self._ctrl_half
        xy_before = self._velocity_point()
        mujoco.mj_step(self.model, self.data, nstep=self.n_substeps)
        self._steps += 1

        if self._diverged():
            self._needs_reset = True
            info = {"terminated": True, "diverged": True, "reward_terms": {}}
            return self._last_obs.copy(), 0.0, True, info

        if self.task.needs_contact_forces:
            mujoco.mj_rnePostConstraint(self.model, self.data)
        if self.task.resample_command_every and self._steps % self.task.resample_command_every == 0:
            self._command = self.task.command_sampler(self._rng)
        ctx = StepContext(self.model, self.data, self.dt, a, xy_before, self._velocity_point(), self._command)
        terminated = bool(self.task.termination(ctx)) if self.task.termination else False
        ctx.healthy = not terminated
        reward, terms = self.reward_fn(ctx)
        obs = self._observation()
        self._last_obs = obs
        info = {"terminated": terminated, "diverged": False, "reward_terms": terms}
        return obs.copy(), float(reward), terminated, info

    # ------------------------------------------------------------------ helpers
    def horizontal_position(self) -> np.ndarray:
        """World (x, y) of the point whose velocity the task rewards (root or centre of mass), now."""
        return self._velocity_point()

    def _velocity_point(self) -> np.ndarray:
        """Horizontal position whose finite difference over a step is the task's velocity."""
        point = self.task.velocity_point
        if point == "com":
            return self._mass_fraction @ self.data.xipos[:, :2]
        if point == "root" and self._root_xy_idx.size:
            return self._root_xy_proj @ self.data.qpos[self._root_xy_idx]
        return self.data.xpos[self._point_body, :2].copy()

    def _divergence_count(self) -> int:
        warning = self.data.warning
        return sum(warning[w].number for w in _DIVERGENCE_WARNINGS)

    def _diverged(self) -> bool:
        return self._divergence_count() != self._warnings0

    def _observation(self) -> np.ndarray:
        parts = [self.data.qpos[self._layout.qpos_idx], self.data.qvel[self._layout.qvel_idx]]
        if self.draw is not None:
            parts.append(self.draw.features(self.draw.values[self._drawn]))
        elif self.task.command_features is not None:
            parts.append(self.task.command_features(self._command))
        obs = np.concatenate(parts)
        return obs if self._mask_all else obs[self.obs_mask]

    def get_sim_state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.data.qpos.copy(), self.data.qvel.copy()

    def set_sim_state(self, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
        """Put the simulator in a given state (e.g. to replay a dataset) and return its observation."""
        self.data.qpos[:], self.data.qvel[:] = qpos, qvel
        mujoco.mj_forward(self.model, self.data)
        self._needs_reset = False
        self._warnings0 = self._divergence_count()
        self._last_obs = self._observation()
        return self._last_obs.copy()

    @property
    def command(self) -> np.ndarray:
        return self._command.copy()

    def create_dataset(self, **kwargs: Any):
        """The dataset of this env's Task-ID (see `loco_il.datasets.create_dataset`)."""
        from loco_il.datasets import create_dataset
        return create_dataset(self, **kwargs)

    # ------------------------------------------------------------------ rendering
    def render(self, record: bool = False) -> np.ndarray | None:
        from loco_il.environments.rendering import render_frame
        return render_frame(self)

    def close(self) -> None:
        """`stop()` under the name Gymnasium users expect."""
        self.stop()

    def stop(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
