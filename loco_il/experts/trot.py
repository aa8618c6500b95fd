"""The trot controller as an env-level expert: the quadrupeds' built-in `perfect` / `preference` experts.

There are no RL-trained quadruped experts; `TrotExpert` makes the model-based trot controller
(`loco_il.motion.gait.TrotController`: CPG + foot trajectories + leg IK + PD/Raibert) act like any policy:
one normalized action per env step, passed to ``env.step`` and held by the env over its substeps.
Each step it reads the simulator state at the start of the step, advances the gait and computes
the controls once (`TrotController.held_ctrl`):

* torque motors (LocoMuJoCo's A1): ``tau = Kp (q_ref - q) + Kd (dq_ref - dq) + tau_ff`` from the
  state at the start of the step toward the end-of-step joint targets, ``action = tau / gear``
  (the action is the normalized motor torque);
* position servos (Menagerie's Go1): the end-of-step joint targets plus the feed-forward / damping
  offset, normalized to the servos' control range (the action is the normalized target).

This differs from the `real` provider (`loco_il.datasets.gait`), which runs the PD at the physics
rate (its per-substep torques are no env action). Measured (10 episodes of ``simple``, 1000 steps, seeds
``episode_seeds(0, 10)``, mean velocity after the first second): A1 0 falls, 0.502 m/s, return
748.8 +- 30.2; Go1 0 falls, 0.502 m/s, return 751.6 +- 22.0 (the speed ramp from standing over the
first 0.5 s and the trot's velocity oscillation keep the reward ``exp(-5 |v - v_cmd|)`` below 1). On ``hard``
(a direction drawn per episode; ``baselines.yaml``, same seeds) the controller turns toward it: A1 0 falls,
return 731.1 +- 32.1; Go1 0 falls, 718.8.

Interface (the policy contract of :mod:`loco_il.experts.files`): the rollout calls
``start_episode(env, seed)`` after every ``env.reset()``; the expert then follows that env's
simulator state (``env.model`` / ``env.data``, which it only reads: it copies the state into a
private ``MjData`` for its kinematics), so the recorded actions replay exactly. The controller has
internal state (oscillator phases, foot targets, velocity integral): the action is a deterministic
function of the episode's states so far, not of the current observation alone.

Per-episode variation: as in the `real` data, a generator seeded with the episode's reset seed draws
the episode's gait (`loco_il.motion.gait.GaitVariation`: frequency, swing height, body height,
stance width, initial phase jitter), so the episodes of a dataset differ although ``simple`` always
starts from the same state.

It registers as the built-in expert of `TROT_EXPERT_TASKS` (`loco_il.experts.registry`).

Preference levels (`trot_levels`): the same expert with i.i.d. Gaussian noise of std ``sigma_k``
added to the normalized action each step (before the env's clipping; the recorded action is the
noisy one), ``sigma_k = sigma_max / 2**k`` for k = 0..3, ``sigma_max`` per body
(`PREFERENCE_NOISE_MAX`: A1 0.4, Go1 0.2 -- the position targets are more sensitive than the
torques). The noise generator is seeded with the episode's reset seed. Measured mean returns
(the default 25 episodes per level, seed 0; ``baselines.yaml``): A1 sigma 0.4 / 0.2 / 0.1 / 0.05 ->
142 (23 of 25 fall) / 565 / 669 / 729; Go1 sigma 0.2 / 0.1 / 0.05 / 0.025 -> 92 (22 of 25 fall) /
319 / 552 / 664. The preference provider ranks the sets by their measured mean return.

``checksum()`` hashes `TROT_EXPERT_VERSION`, the task, the controller parameters, the variation
ranges, the noise scale and the model's fingerprint: it is part of the datasets' cache key.
"""
from __future__ import annotations

import hashlib
import json
import types
from dataclasses import asdict
from typing import Any

import mujoco
import numpy as np

from loco_il.environments.base import action_map
from loco_il.environments.registry import task_key
from loco_il.experts.registry import register_builtin_expert
from loco_il.motion.gait.controller import ControllerParams, TrotController
from loco_il.motion.gait.quadruped import goal_speed, is_quadruped, model_fingerprint
from loco_il.motion.gait.variation import GaitVariation
from loco_il.utils.hashing import plain_json

#: bump when the expert's actions change for the same parameters (invalidates cached datasets)
TROT_EXPERT_VERSION = 1
#: tasks whose built-in expert is the trot controller
TROT_EXPERT_TASKS = ("UnitreeA1.simple", "UnitreeA1.hard", "UnitreeGo1.simple", "UnitreeGo1.hard")
#: largest action-noise std of the preference levels, per body (normalized action units)
PREFERENCE_NOISE_MAX = {"UnitreeA1": 0.4, "UnitreeGo1": 0.2}
PREFERENCE_LEVELS = 4
SOURCE = "model-based trot controller (CPG + leg IK + PD/Raibert, loco_il.motion.gait), not an RL policy"


def _task_env(env_or_task: Any) -> tuple[Any, bool]:
    """(env, made_here) for an env or a task key / Task-ID."""
    if isinstance(env_or_task, str):
        from loco_il.environments.registry import make, parse_task_id
        tid = parse_task_id(env_or_task)
        body = f"{tid.body}{'-' + tid.variant if tid.variant else ''}"
        return make(f"{body}.{tid.task}.perfect"), True
    return env_or_task, False


class TrotExpert:
    """`TrotController` as a deterministic env-level policy (see the module docstring).

    ``env``: an env (or Task-ID) of the task, used for the task, the dimensions and the model
    fingerprint; the expert acts in whatever env `start_episode` gives it. ``params``: controller
    parameters (default: the task's goal speed, other defaults of `ControllerParams`);
    ``variation``: per-episode gait variation (None: the same gait every episode);
    ``action_noise``: std of the Gaussian noise added to the normalized action (preference levels).
    """

    def __init__(self, env: Any, params: ControllerParams | None = None,
                 variation: GaitVariation | None = GaitVariation(), action_noise: float = 0.0):
        env, made = _task_env(env)
        try:
            if not is_quadruped(env):
                raise ValueError(f"{env.task_id} is not a quadruped; the trot expert walks quadrupeds")
            self.task = task_key(env)
            self.params = params or ControllerParams(speed=goal_speed(env))
            self.variation = variation
            self.action_noise = float(action_noise)
            if self.action_noise < 0:
                raise ValueError(f"action_noise must be >= 0, got {action_noise}")
            self.obs_dim = int(env.full_obs_spec.dim)
            self.act_dim = int(env.model.nu)
            self._fingerprint = model_fingerprint(env)
        finally:
            if made:
                env.stop()
        self.metadata = {"task_id": self.task, "algorithm": "model-based trot controller (no training)",
                         "source": SOURCE, "controller_version": TROT_EXPERT_VERSION,
                         "action_noise": self.action_noise}
        noise = f", action noise std {self.action_noise:g}" if self.action_noise else ""
        self.description = f"TrotExpert v{TROT_EXPERT_VERSION} ({SOURCE}{noise})"
        self._env: Any = None
        self._ctl: TrotController | None = None

    # ------------------------------------------------------------------ policy contract
    def checksum(self) -> str:
        fields = {"version": TROT_EXPERT_VERSION, "task": self.task, "params": plain_json(asdict(self.params)),
                  "variation": None if self.variation is None else plain_json(asdict(self.variation)),
                  "action_noise": self.action_noise, "model": self._fingerprint}
        return hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()

    def start_episode(self, env: Any, seed: int) -> None:
        """Start following ``env`` (call right after its ``reset()``); ``seed`` draws the episode's gait and noise."""
        if int(env.model.nu) != self.act_dim:
            raise ValueError(f"{env.task_id} has {env.model.nu} actuators; this expert was built for {self.act_dim}")
        self._env = env
        model = env.model
        self._data = mujoco.MjData(model)     # private copy of the state: env.data is only read
        self._sync()
        shim = types.SimpleNamespace(model=model, data=self._data, dt=float(env.dt), n_substeps=int(env.n_substeps))
        command = env.command
        direction = float(command[0]) if command.size else 0.0
        rng = np.random.default_rng(int(seed))
        ctl = TrotController(shim, self.params)
        ctl.reset(direction)
        if self.variation is not None:       # same draws as the `real` provider's episode of this seed
            params, jitter = self.variation.draw(self.params, rng, ctl.body_height)
            ctl = TrotController(shim, params)
            ctl.reset(direction, rng=rng, phase_jitter=jitter)
        self._ctl = ctl
        self._noise_rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(0x7e0,)))
        self._center, self._half = action_map(model)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if self._ctl is None:
            raise RuntimeError("TrotExpert follows the simulator state: call start_episode(env, seed) after "
                               "env.reset() (loco_il.environments.episodes.run_episode does)")
        self._sync()
        ctl = self._ctl
        action = np.zeros(self.act_dim)
        action[ctl.act] = (ctl.env_step_ctrl() - self._center[ctl.act]) / self._half[ctl.act]
        if self.action_noise:
            action += self.action_noise * self._noise_rng.standard_normal(self.act_dim)
        return np.clip(action, -1.0, 1.0)

    def _sync(self) -> None:
        d = self._env.data
        self._data.qpos[:], self._data.qvel[:] = d.qpos, d.qvel
        mujoco.mj_forward(self._env.model, self._data)

    def __repr__(self) -> str:
        return f"TrotExpert({self.task}, action_noise={self.action_noise:g})"


def trot_expert(env: Any) -> TrotExpert:
    """The built-in `perfect` expert of a quadruped task."""
    return TrotExpert(env)


def trot_levels(env: Any, n_levels: int = PREFERENCE_LEVELS) -> list[TrotExpert]:
    """The built-in preference levels: ``sigma_max / 2**k`` action noise, noisiest first."""
    env, made = _task_env(env)
    try:
        sigma_max = PREFERENCE_NOISE_MAX[env.body_name]
        return [TrotExpert(env, action_noise=sigma_max / 2 ** k) for k in range(n_levels)]
    finally:
        if made:
            env.stop()


def _register() -> None:
    for key in TROT_EXPERT_TASKS:
        register_builtin_expert(key, trot_expert, trot_levels, SOURCE, replace=True)


_register()

__all__ = ["PREFERENCE_LEVELS", "PREFERENCE_NOISE_MAX", "SOURCE", "TROT_EXPERT_TASKS", "TROT_EXPERT_VERSION",
           "TrotExpert", "trot_expert", "trot_levels"]
