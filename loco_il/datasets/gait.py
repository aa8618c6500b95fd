"""The quadrupeds' `real` datasets: state trajectories of the trot controller, recorded in the env.

LocoMuJoCo's UnitreeA1 `real` data came from a model-predictive controller; loco_il records its own
gait generator instead (`loco_il.motion.gait.TrotController`: CPG + foot trajectories + leg IK +
PD/Raibert, run through the body's actuators at the env's timestep and substeps). Only states are kept
(``actions=None``), like every `real` dataset.

Episode ``i`` uses the reset seed ``episode_seeds(seed, ...)[i]`` (the scheme of the `perfect` data):
``env.seed(s); env.reset()`` draws the task command (the walking direction of `hard`), and a
generator seeded with ``s`` draws the episode's gait variation (`loco_il.motion.gait.GaitVariation`:
gait frequency, swing height, body height, stance width, initial phase jitter), so episodes differ. The
controller walks for ``warmup`` seconds (start from standing, speed ramp, first part of the turn), then
``episode_steps`` env steps (default: the task horizon) are recorded: ``obs`` / ``next_obs`` are exactly what the env
emits (`LocoEnv.set_sim_state`, full observations with the command features), rewards are the env's
own reward, ``absorbing`` is always False.

An episode is kept only if the robot neither fell (the task's termination) nor diverged, its mean
velocity (displacement / time over the recorded part) is within ``speed_tolerance`` of the goal speed
and its direction within ``direction_tolerance_deg`` of the command. Rejected episodes are replaced by
further seeds (up to ``max_attempts``). ``info["gait_quality"]`` holds the quality numbers: mean speed,
direction and heading errors, foot slip during stance, trunk tilt, mean reward, fraction kept.

The same controller is also the quadrupeds' `perfect` / `preference` expert
(`loco_il.experts.trot.TrotExpert`): there it acts as an env-level policy -- one normalized action per env
step, computed from the state at the start of the step and held by the env over its substeps (the torques of the
PD loop here, recomputed every substep, are not an env action) -- so those datasets have actions
that replay exactly. That expert is a model-based controller, not an RL policy; its returns are in
``baselines.yaml``.

Dispatch: `loco_il.motion.gait.is_quadruped(env)` tells whether an env's `real` data comes from here;
`quadruped_real_provider` has the provider signature (``provider(env, **kwargs)``, cached on disk like
the `perfect` data); `real_dispatcher(other)` wraps another `real` provider (the humanoids' motion
capture) so that quadrupeds come here.
"""
from __future__ import annotations

import sys
import time
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import mujoco
import numpy as np

from loco_il.datasets.providers.cache import (cache_key, datasets_cache_dir, init_states_path, regenerate_hint,
                                              safe_name, save_to_cache)
from loco_il.datasets.providers.init_states import InitStates
from loco_il.datasets.providers.registry import ProviderUnavailableError
from loco_il.datasets.trajectory import DatasetError, Trajectories
from loco_il.environments.episodes import episode_seeds
from loco_il.environments.registry import make
from loco_il.motion.gait.controller import ControllerParams, TrotController, wrap_angle
from loco_il.motion.gait.quadruped import goal_speed, is_quadruped, model_fingerprint
from loco_il.motion.gait.variation import GaitVariation
from loco_il.utils.hashing import plain_json

#: bump when the generator changes the data it produces (invalidates caches)
GAIT_GENERATOR_VERSION = 1
DEFAULT_REAL_EPISODES = 50
SOURCE = "loco_il gait generator (trot CPG + leg IK + PD/Raibert controller, simulated)"
_DIVERGENCE_WARNINGS = (int(mujoco.mjtWarning.mjWARN_BADQPOS), int(mujoco.mjtWarning.mjWARN_BADQVEL),
                        int(mujoco.mjtWarning.mjWARN_BADQACC))


# ----------------------------------------------------------------------------- one episode
@dataclass
class GaitEpisode:
    """One recorded episode and its quality numbers."""

    seed: int
    command: np.ndarray
    obs: np.ndarray                 # (T, obs_dim)
    next_obs: np.ndarray            # (T, obs_dim)
    rewards: np.ndarray             # (T,)
    qpos0: np.ndarray               # simulator state when recording started
    qvel0: np.ndarray
    terminated: bool
    diverged: bool
    metrics: dict[str, float] = field(default_factory=dict)
    params: dict[str, Any] = field(default_factory=dict)

    @property
    def fell(self) -> bool:
        return self.terminated or self.diverged


class _RootXY:
    """Horizontal position of the root body read from qpos (valid right after mj_step, before mj_forward)."""

    def __init__(self, model: mujoco.MjModel):
        if model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE:
            adr = int(model.jnt_qposadr[0])
            self.idx, self.proj, self.offset = np.array([adr, adr + 1]), np.eye(2), np.zeros(2)
        else:
            root = int(model.jnt_bodyid[0])
            slides = [j for j in range(model.njnt) if model.jnt_bodyid[j] == root
                      and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE]
            self.idx = np.array([model.jnt_qposadr[j] for j in slides], dtype=np.int64)
            self.proj = np.array([model.jnt_axis[j][:2] for j in slides]).T.reshape(2, len(slides))
            self.offset = model.body_pos[root, :2].copy()

    def __call__(self, data: mujoco.MjData) -> np.ndarray:
        return self.offset + self.proj @ data.qpos[self.idx]


def _divergences(data: mujoco.MjData) -> int:
    return sum(int(data.warning[w].number) for w in _DIVERGENCE_WARNINGS)


def _tilt(R: np.ndarray) -> float:
    """Angle between the trunk's z axis and the vertical (rad)."""
    return float(np.arccos(np.clip(R[2, 2], -1.0, 1.0)))


def run_gait_episode(env: Any, seed: int, *, episode_steps: int | None = None, warmup: float = 1.0,
                     params: ControllerParams | None = None, variation: GaitVariation | None = GaitVariation(),
                     speed: float | None = None) -> GaitEpisode:
    """Reset ``env`` with ``seed``, walk ``warmup`` seconds, then record ``episode_steps`` env steps.

    ``env`` must emit full observations for a dataset (``create_dataset`` masks later); the episode stops
    early if the task's termination fires or the simulation diverges.
    """
    from loco_il.environments.tasks import StepContext

    env.seed(int(seed))
    env.reset()
    command = env.command
    direction = float(command[0]) if command.size else 0.0
    base = params or ControllerParams()
    if speed is not None:
        base = ControllerParams(**{**{k: v for k, v in asdict(base).items() if k != "gait"},
                                   "gait": base.gait, "speed": float(speed)})
    rng = np.random.default_rng(int(seed))
    ctl = TrotController(env, base)          # built after reset: a randomized env recompiles its model
    ctl.reset(direction)
    jitter = 0.0
    if variation is not None:
        p, jitter = variation.draw(base, rng, ctl.body_height)
        ctl = TrotController(env, p)
        ctl.reset(direction, rng=rng, phase_jitter=jitter)
    p = ctl.params
    n_warm = int(round(warmup / env.dt))
    n_rec = int(episode_steps if episode_steps is not None else env.info.horizon)
    task, model, data = env.task, env.model, env.data
    root_xy = _RootXY(model)
    warn0 = _divergences(data)
    obs = env.set_sim_state(data.qpos.copy(), data.qvel.copy())
    obs_l, next_l, rew_l = [], [], []
    qpos0, qvel0 = data.qpos.copy(), data.qvel.copy()
    terminated = diverged = False
    u = np.array([np.cos(direction), np.sin(direction)])
    xy_start = root_xy(data)
    slips, heading_err, tilts = [], [], []
    for t in range(n_warm + n_rec):
        if t == n_warm:
            qpos0, qvel0 = data.qpos.copy(), data.qvel.copy()
            xy_start = root_xy(data)
        xy_before = root_xy(data)
        ctl.step()
        if _divergences(data) != warn0 or not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
            diverged = True
            break
        if task.needs_contact_forces:
            mujoco.mj_rnePostConstraint(model, data)
        ctx = StepContext(model, data, env.dt, ctl.normalized_ctrl(), xy_before, root_xy(data), command)
        terminated = bool(task.termination(ctx)) if task.termination else False
        ctx.healthy = not terminated
        reward, _ = env.reward_fn(ctx)
        next_obs = env.set_sim_state(data.qpos.copy(), data.qvel.copy())   # also runs mj_forward
        if t >= n_warm:
            obs_l.append(obs)
            next_l.append(next_obs)
            rew_l.append(float(reward))
            down = ctl.foot_contacts() & ctl.cpg.in_stance()
            if down.any():
                slips.extend(ctl.contact_point_speeds()[down])
            heading_err.append(abs(wrap_angle(ctl.heading() - direction)))
            tilts.append(_tilt(data.xmat[ctl.trunk].reshape(3, 3)))
        obs = next_obs
        if terminated:
            break
    n = len(obs_l)
    duration = max(n, 1) * env.dt
    disp = root_xy(data) - xy_start
    vel = disp / duration
    metrics = {
        "steps": float(n),
        "speed": float(np.linalg.norm(vel)),                    # |mean velocity| (m/s)
        "forward_speed": float(vel @ u),                        # along the command (m/s)
        "direction_error_deg": float(np.degrees(abs(wrap_angle(np.arctan2(vel[1], vel[0]) - direction))))
        if np.linalg.norm(vel) > 1e-6 else 180.0,
        "heading_error_deg": float(np.degrees(np.mean(heading_err))) if heading_err else float("nan"),
        "foot_slip": float(np.mean(slips)) if slips else float("nan"),   # m/s, contact points of stance feet
        "foot_slip_p90": float(np.percentile(slips, 90)) if slips else float("nan"),
        "max_tilt_deg": float(np.degrees(np.max(tilts))) if tilts else float("nan"),
        "mean_reward": float(np.mean(rew_l)) if rew_l else 0.0,
    }
    gait = {"frequency": p.gait.frequency, "duty": p.gait.duty, "swing_height": p.gait.swing_height,
            "body_height": ctl.body_height, "stance_width": p.stance_width, "phase_jitter": jitter,
            "speed": p.speed}
    dim = env.obs_spec.dim
    return GaitEpisode(int(seed), command.copy(), np.asarray(obs_l, dtype=np.float64).reshape(n, dim),
                       np.asarray(next_l, dtype=np.float64).reshape(n, dim), np.asarray(rew_l, dtype=np.float64),
                       qpos0, qvel0, terminated, diverged, metrics, gait)


# ----------------------------------------------------------------------------- dataset
def _generation_env(env: Any, fresh: bool = False) -> Any:
    """``env`` itself when it emits plain full observations from its own start state (and not ``fresh``),
    else a new env of the same body, variant and task (default reward, no masks, no randomization)."""
    if isinstance(env, str):
        return make(env)
    plain = (bool(np.all(env.obs_mask)) and env.init_state_sampler is None and env.randomization is None)
    if plain and not fresh:
        return env
    key = f"{env.body_name}{'-' + env.variant if env.variant else ''}.{env.task_name}.{env.dataset_type}"
    return make(key)


def keep_episode(ep: GaitEpisode, goal_speed: float, n_expected: int, speed_tolerance: float,
                 direction_tolerance_deg: float) -> bool:
    """The acceptance rule (see the module docstring)."""
    return (not ep.fell and int(ep.metrics["steps"]) == n_expected
            and abs(ep.metrics["speed"] - goal_speed) <= speed_tolerance * goal_speed
            and ep.metrics["direction_error_deg"] <= direction_tolerance_deg)


def generate_episodes(env: Any, n_episodes: int = DEFAULT_REAL_EPISODES, seed: int = 0, *,
                      episode_steps: int | None = None, warmup: float = 1.0,
                      params: ControllerParams | None = None, variation: GaitVariation | None = GaitVariation(),
                      speed_tolerance: float = 0.2, direction_tolerance_deg: float = 15.0,
                      max_attempts: int | None = None, log: Callable[[str], None] | None = None
                      ) -> tuple[list[GaitEpisode], dict[str, Any]]:
    """Kept episodes and a summary (quality numbers, attempts, kept fraction)."""
    if n_episodes < 1:
        raise ValueError(f"n_episodes must be >= 1, got {n_episodes}")
    if not is_quadruped(env):
        raise ValueError(f"{getattr(env, 'task_id', env)} is not a quadruped; the gait generator walks quadrupeds")
    gen = _generation_env(env)
    goal = goal_speed(gen)
    steps = int(episode_steps if episode_steps is not None else gen.info.horizon)
    max_attempts = int(max_attempts if max_attempts is not None else 2 * n_episodes + 5)
    seeds = episode_seeds(seed, max_attempts)
    kept: list[GaitEpisode] = []
    rejected: list[dict[str, Any]] = []
    t0 = time.perf_counter()
    attempts = 0
    for s in seeds:
        if len(kept) == n_episodes:
            break
        attempts += 1
        ep = run_gait_episode(gen, int(s), episode_steps=steps, warmup=warmup, params=params, variation=variation,
                              speed=goal if params is None else None)
        if keep_episode(ep, goal, steps, speed_tolerance, direction_tolerance_deg):
            kept.append(ep)
        else:
            rejected.append({"seed": int(s), "fell": ep.fell, **ep.metrics})
        if log is not None and (attempts % max(1, n_episodes // 10) == 0 or len(kept) == n_episodes):
            log(f"[loco_il.datasets] {gen.task_id} gait: {len(kept)}/{n_episodes} kept after {attempts} attempts, "
                f"{time.perf_counter() - t0:.1f}s")
    if not kept:
        raise DatasetError(f"the gait generator kept no episode of {gen.task_id} in {attempts} attempts "
                           f"(e.g. {rejected[:2]})")
    if len(kept) < n_episodes:
        warnings.warn(f"{gen.task_id}: the gait generator kept only {len(kept)} of {n_episodes} episodes "
                      f"in {attempts} attempts", RuntimeWarning, stacklevel=2)

    def mean(key: str) -> float:
        return float(np.mean([e.metrics[key] for e in kept]))

    summary = {
        "goal_speed": goal, "episodes": len(kept), "attempts": attempts, "kept_fraction": len(kept) / attempts,
        "mean_speed": mean("speed"), "mean_forward_speed": mean("forward_speed"),
        "mean_direction_error_deg": mean("direction_error_deg"), "mean_heading_error_deg": mean("heading_error_deg"),
        "mean_foot_slip": mean("foot_slip"), "mean_foot_slip_p90": mean("foot_slip_p90"),
        "max_tilt_deg": float(np.max([e.metrics["max_tilt_deg"] for e in kept])),
        "mean_reward": mean("mean_reward"), "rejected": rejected[:20],
    }
    return kept, summary


def episodes_to_trajectories(env: Any, episodes: list[GaitEpisode], info: Mapping[str, Any]) -> Trajectories:
    obs = np.concatenate([e.obs for e in episodes])
    nxt = np.concatenate([e.next_obs for e in episodes])
    rew = np.concatenate([e.rewards for e in episodes])
    last = np.concatenate([np.arange(len(e.rewards)) == len(e.rewards) - 1 for e in episodes])
    return Trajectories(obs, nxt, None, rew, np.zeros(len(rew), dtype=bool), last, dict(info))


def _base_info(gen: Any, seed: int, summary: Mapping[str, Any], episodes: list[GaitEpisode],
               settings: Mapping[str, Any]) -> dict[str, Any]:
    return {
        "task_id": gen.task_id, "dataset_type": "real", "source": SOURCE,
        "obs_names": list(gen.full_obs_spec.names), "simulator": f"mujoco {mujoco.__version__}",
        "seed": int(seed), "policy_checksum": None,
        "generator": f"loco_il.datasets.gait v{GAIT_GENERATOR_VERSION}",
        "control": ("PD at the physics rate on torque motors / targets on position servos, through the "
                    "body's actuators, env timestep and substeps"),
        "reward": "task default", "gait_settings": dict(settings), "gait_quality": dict(summary),
        "episode_seeds": [e.seed for e in episodes], "episode_commands": [e.command.tolist() for e in episodes],
        "episode_gaits": [e.params for e in episodes],
        "episode_metrics": [{k: v for k, v in e.metrics.items()} for e in episodes],
    }


def quadruped_real_dataset(env: Any, n_episodes: int = DEFAULT_REAL_EPISODES, seed: int = 0, *,
                           episode_steps: int | None = None, warmup: float = 1.0,
                           params: ControllerParams | None = None,
                           variation: GaitVariation | None = GaitVariation(), speed_tolerance: float = 0.2,
                           direction_tolerance_deg: float = 15.0, max_attempts: int | None = None,
                           return_init_states: bool = False, verbose: bool = False):
    """Generate a quadruped task's `real` dataset (full observations, ``actions=None``); not cached.

    ``env``: a quadruped `LocoEnv` or Task-ID. It is used for generation (it gets seeded and reset)
    when it emits full observations from its own start state; otherwise a fresh env of the same
    body, variant and task is made. With ``return_init_states`` also returns the
    :class:`~loco_il.datasets.providers.InitStates` (simulator state where each recorded episode starts).
    """
    gen = _generation_env(env)
    log = (lambda msg: print(msg, file=sys.stderr, flush=True)) if verbose else None
    episodes, summary = generate_episodes(gen, n_episodes, seed, episode_steps=episode_steps, warmup=warmup,
                                          params=params, variation=variation, speed_tolerance=speed_tolerance,
                                          direction_tolerance_deg=direction_tolerance_deg,
                                          max_attempts=max_attempts, log=log)
    settings = {"n_episodes": int(n_episodes), "episode_steps": int(episode_steps or gen.info.horizon),
                "warmup": float(warmup), "speed_tolerance": float(speed_tolerance),
                "direction_tolerance_deg": float(direction_tolerance_deg),
                "params": None if params is None else plain_json(asdict(params)),
                "variation": None if variation is None else plain_json(asdict(variation))}
    data = episodes_to_trajectories(gen, episodes, _base_info(gen, seed, summary, episodes, settings))
    if not return_init_states:
        return data
    init = InitStates(np.array([e.qpos0 for e in episodes]), np.array([e.qvel0 for e in episodes]),
                      np.array([e.seed for e in episodes], dtype=np.int64))
    return data, init


# ----------------------------------------------------------------------------- provider (cached)
def _cache_path(gen: Any, n_episodes: int, seed: int, fields: Mapping[str, Any]) -> Path:
    key = f"{gen.body_name}{'-' + gen.variant if gen.variant else ''}.{gen.task_name}"
    name = f"real-gait-n{int(n_episodes)}-seed{int(seed)}-{cache_key(fields)}.npz"
    return datasets_cache_dir() / safe_name(key) / name


def quadruped_real_provider(env: Any, *, n_episodes: int | None = None, generation_seed: int = 0,
                            regenerate: bool = False, verbose: bool = True, **kwargs: Any):
    """`real` provider for quadrupeds (signature of `loco_il.datasets.providers`): the gait dataset,
    cached as ``<cache>/<Body>.<task>/real-gait-n<N>-seed<S>-<key>.npz`` plus its ``.init_states.npz``.

    Returns ``(Trajectories, InitStates)``. Extra ``kwargs`` go to `quadruped_real_dataset`
    (e.g. ``episode_steps``, ``warmup``, ``speed_tolerance``).
    """
    allowed = {"episode_steps", "warmup", "params", "variation", "speed_tolerance", "direction_tolerance_deg",
               "max_attempts"}
    unknown = set(kwargs) - allowed
    if unknown:
        raise TypeError(f"the quadruped `real` provider got unexpected arguments {sorted(unknown)}; "
                        f"it accepts n_episodes, generation_seed, regenerate, verbose, {sorted(allowed)}")
    gen = _generation_env(env, fresh=True)     # the caller's env keeps its random stream and state
    n = DEFAULT_REAL_EPISODES if n_episodes is None else int(n_episodes)
    fields = {"generator": GAIT_GENERATOR_VERSION, "task": gen.task_id, "n_episodes": n,
              "seed": int(generation_seed), "mujoco": mujoco.__version__, "model": model_fingerprint(gen),
              "kwargs": plain_json({k: asdict(v) if hasattr(v, "__dataclass_fields__") else v
                                   for k, v in sorted(kwargs.items())})}
    path = _cache_path(gen, n, generation_seed, fields)
    side = init_states_path(path)
    if not regenerate and path.exists() and side.exists():
        hint = regenerate_hint(path)
        data = Trajectories.load(path, regenerate_hint=hint,
                                 expect={"obs_names": list(gen.full_obs_spec.names), "dataset_type": "real",
                                         "act_dim": None})
        init = InitStates.load(side, regenerate_hint=hint, n_episodes=data.n_trajectories,
                               nq=int(gen.model.nq), nv=int(gen.model.nv))
        return data, init
    if verbose:
        print(f"[loco_il.datasets] generating the gait `real` dataset of {gen.task_id}: {n} episodes, "
              f"seed {generation_seed} -> {path}", file=sys.stderr, flush=True)
    try:
        data, init = quadruped_real_dataset(gen, n, int(generation_seed), return_init_states=True,
                                            verbose=verbose, **kwargs)
    finally:
        gen.stop()
    info = dict(data.info)
    info["cache_fields"] = fields
    data = data.replace(info=info)
    save_to_cache(path, data, init)   # a cache that cannot be written only warns
    return data, init


def real_dispatcher(other: Callable[..., Any] | None) -> Callable[..., Any]:
    """A `real` provider that sends quadrupeds to `quadruped_real_provider` and everything else to ``other``."""
    def provider(env: Any, **kwargs: Any):
        if is_quadruped(env):
            return quadruped_real_provider(env, **kwargs)
        if other is None:
            raise ProviderUnavailableError(f"no `real` provider for {getattr(env, 'task_id', env)}")
        return other(env, **kwargs)
    provider.__qualname__ = "real_dispatcher.provider"
    return provider


__all__ = ["DEFAULT_REAL_EPISODES", "GAIT_GENERATOR_VERSION", "GaitEpisode", "episodes_to_trajectories",
           "generate_episodes", "keep_episode", "quadruped_real_dataset", "quadruped_real_provider", "real_dispatcher",
           "run_gait_episode"]
