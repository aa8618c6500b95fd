"""The `real` dataset provider: human motion capture retargeted to the task's robot.

``LocoEnv.make("UnitreeH1.walk.real").create_dataset()`` lands here (the provider registry imports
this module on first use of a `real` dataset).  For the env's task it

1. finds the task's motion files (`loco_il.motion.mocap.clips`: the task's ``TASK_CLIPS``, or
   ``clips=[...]``) in ``$LOCO_IL_MOCAP`` (if set), the clips shipped in the package or
   ``~/.cache/loco_il/mocap``;
2. loads them (DeepMimic ``.txt`` or BVH ``.bvh``), trims them, repeats cyclic clips to the
   wanted length, and retargets each to the robot (:func:`~loco_il.motion.mocap.retarget.retarget_clip`,
   keypoint map from :mod:`~loco_il.motion.mocap.robot_maps`);
3. turns each clip into one episode of full observations (:func:`result_to_trajectories`:
   ``env.set_sim_state`` on the robot's ``qpos``/``qvel``), no actions, rewards of the task evaluated on the
   motion (with a zero action: motion capture has none), absorbing False, ``last`` at the clip's end; ``info`` holds the sources with their licences, the retargeting
   quality metrics (per episode and overall) and the usual keys;
4. caches the result like the expert datasets: ``$LOCO_IL_DATASETS`` (or
   ``~/.cache/loco_il/datasets``) ``/<Body>.<task>/real-<key>.npz`` plus the initial states of the
   episodes (``.init_states.npz``); the key hashes the motion files' contents, the clip list, the
   solver version and options, the robot model and the MuJoCo version.

Tasks with motion: ``walk``, ``run`` and ``carry`` (the clips are listed in `loco_il.motion.mocap.clips`).
Other tasks (``stand``, quadruped tasks) have no motion here: a clear
error says so.  Bodies need a keypoint map (every humanoid has one).

Tasks that draw a version of the model per episode (``env.draw``: the carried mass of ``carry``, the
body size of the 4Ages humanoids) get every clip once per version the Task-ID's mode draws from, in
the order of the versions: the motion is retargeted to the draw's reference version and carried to
each version by the draw's ``state_map`` (4Ages: root slides scaled by the size), the observation's
draw entries are that version's.
"""
from __future__ import annotations

import hashlib
import sys
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any, Iterable, Mapping, Optional, Sequence

import mujoco
import numpy as np

from loco_il.datasets.gait import real_dispatcher
from loco_il.datasets.providers.cache import (cache_key, datasets_cache_dir, init_states_path, regenerate_hint,
                                              safe_name, save_to_cache)
from loco_il.datasets.providers.expert import generation_env
from loco_il.datasets.providers.init_states import InitStates
from loco_il.datasets.providers.registry import (ProviderUnavailableError, register_real_provider,
                                                 registered_providers)
from loco_il.datasets.trajectory import Trajectories
from loco_il.environments.registry import task_key
from loco_il.environments.tasks import StepContext
from loco_il.motion.mocap.clips import TASK_CLIPS, ClipSpec, find_motion_files, load_motion, provenance
from loco_il.motion.mocap.retarget import (RETARGET_VERSION, RetargetOptions, RetargetResult, RobotKinematics,
                                           retarget_clip)
from loco_il.motion.mocap.robot_maps import ROBOT_MAPS, has_robot_map
from loco_il.utils.hashing import file_sha256

__all__ = ["real_provider", "retarget_task", "result_to_trajectories", "REAL_GENERATOR_VERSION"]

#: bump when the way clips become datasets changes (part of the cache key; the solver has its own version)
REAL_GENERATOR_VERSION = 1


def _model_fingerprint(model: Any) -> str:
    """Hash of what the retargeting depends on in a compiled model."""
    h = hashlib.sha256()
    for name in ("body_pos", "body_quat", "body_parentid", "jnt_type", "jnt_axis", "jnt_pos", "jnt_range",
                 "jnt_limited", "jnt_bodyid", "geom_type", "geom_size", "geom_pos", "geom_quat", "geom_bodyid",
                 "site_pos", "qpos0", "eq_data", "eq_obj1id", "eq_obj2id", "eq_type"):
        h.update(np.ascontiguousarray(getattr(model, name)).tobytes())
    return h.hexdigest()[:16]


# ----------------------------------------------------------------------------- generation


def _log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _as_specs(clips: Optional[Iterable[Any]], task: str, task_id: str) -> tuple[ClipSpec, ...]:
    if clips is None:
        if task not in TASK_CLIPS:
            raise ProviderUnavailableError(
                f"{task_id}: no motion capture is mapped to the task {task!r}; real datasets are built for the "
                f"tasks {', '.join(sorted(TASK_CLIPS))}. Pass clips=[<motion file>, ...] to create_dataset() to "
                f"retarget your own DeepMimic (.txt) or BVH (.bvh) files for this task.")
        return TASK_CLIPS[task]
    out = []
    for c in clips:
        out.append(c if isinstance(c, ClipSpec) else ClipSpec(str(c)))
    if not out:
        raise ValueError("clips must name at least one motion file")
    return tuple(out)


def retarget_task(env: Any, specs: Sequence[ClipSpec], paths: Sequence[Path], options: Any = None,
                  verbose: bool = True) -> tuple[Trajectories, Any, list]:
    """Retarget the clips to ``env`` (a full-observation env) and build the dataset; returns
    ``(trajectories, init_states, results)``."""

    draw = getattr(env, "draw", None)
    if draw is not None:
        env.select_draw(draw.reference)
    kin = RobotKinematics(env)
    results = []
    for spec, path in zip(specs, paths):
        clip, n_cycles = load_motion(path, spec)
        t0 = time.perf_counter()
        res = retarget_clip(env, clip, n_cycles=n_cycles, options=options, kinematics=kin)
        res.source = path.name
        results.append(res)
        if verbose:
            m = res.metrics
            _log(f"[loco_il.datasets] real {env.body_name}.{env.task_name}: {path.name} x{n_cycles} -> "
                 f"{m['frames']} frames in {time.perf_counter() - t0:.1f}s; "
                 f"keypoint error {m['keypoint_error_m']:.3f} m, "
                 f"foot sliding {m['foot_sliding_mps']:.3f} m/s, penetration {m['penetration_max_m']:.4f} m (max), "
                 f"joints in limits {100 * m['in_limits_fraction']:.1f}% of frames")
    if draw is not None:
        data, init = _per_version(env, results)
        return data, init, results
    env.reset()
    data = result_to_trajectories(env, results)
    init = InitStates(np.stack([r.qpos[0] for r in results]), np.stack([r.qvel[0] for r in results]),
                      np.full(len(results), -1, dtype=np.int64))
    return data, init, results


def _per_version(env: Any, results: Sequence[Any]) -> tuple[Trajectories, Any]:
    """Every retargeted clip on every version of the model the env's mode draws from (see the module doc)."""
    from dataclasses import replace


    draw, parts, mapped_all = env.draw, [], []
    for index in env.draw_indices:
        env.select_draw(index)
        value = draw.values[index]
        mapped = []
        for r in results:
            qpos, qvel = r.qpos, r.qvel
            if draw.state_map is not None:
                pairs = [draw.state_map(env.model, q, v, value) for q, v in zip(qpos, qvel)]
                qpos, qvel = np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])
            mapped.append(replace(r, qpos=qpos, qvel=qvel))
        parts.append(result_to_trajectories(env, mapped))
        mapped_all += mapped
    info = dict(parts[0].info)
    for key in ("episode_metrics", "episode_sources", "episode_returns"):
        info[key] = [x for p in parts for x in p.info[key]]
    fractions = [p.info["terminated_fraction"] for p in parts]
    if None not in fractions:
        info["terminated_fraction"] = float(np.average(fractions, weights=[p.n_transitions for p in parts]))
    info["episode_draw_values"] = [float(draw.values[i]) for i in env.draw_indices for _ in results]
    info["draw_entries"] = list(draw.names)
    data = Trajectories.concatenate(parts, info=info)
    init = InitStates(np.stack([r.qpos[0] for r in mapped_all]), np.stack([r.qvel[0] for r in mapped_all]),
                      np.full(len(mapped_all), -1, dtype=np.int64))
    return data, init


def result_to_trajectories(env: Any, results: Sequence[RetargetResult], info: Optional[Mapping[str, Any]] = None,
                           evaluate_reward: bool = True) -> Trajectories:
    """A `real` :class:`Trajectories` (one episode per retargeted clip).

    Observations are what ``env`` emits in each retargeted state (``env.set_sim_state``), so the
    layout is ``env.obs_spec``'s; use a full-observation env (no ``.pomdp``).  Transition ``t`` goes
    from frame ``t`` to frame ``t + 1``; absorbing is False everywhere (a recorded motion does not
    end in a fall) and ``last`` marks each clip's end.  Rewards: with ``evaluate_reward`` the
    task's reward evaluated on the motion (the velocity of the task's reference point from frame t
    to t + 1, with a zero action since motion capture has none), else zeros.  The task's
    termination rule is evaluated too: ``info["terminated_fraction"]`` is the share of transitions
    it would have ended (states outside the task's height / orientation bounds).
    """
    obs_l, nobs_l, last_l, rew_l, term_l = [], [], [], [], []
    task = getattr(env, "task", None)
    can_eval = evaluate_reward and task is not None and hasattr(env, "_velocity_point")
    if can_eval:
        zero = np.zeros(env.model.nu)
    for r in results:
        if r.n_frames < 2:
            raise ValueError("a retargeted clip needs at least 2 frames")
        obs, points = [], []
        for q, v in zip(r.qpos, r.qvel):
            obs.append(env.set_sim_state(q, v))
            if can_eval:
                points.append(env._velocity_point().copy())
        obs = np.asarray(obs, dtype=np.float64)
        n = r.n_frames - 1
        rew, term = np.zeros(n), np.zeros(n, dtype=bool)
        if can_eval:
            cmd = env.command
            for i in range(n):
                env.set_sim_state(r.qpos[i + 1], r.qvel[i + 1])
                ctx = StepContext(env.model, env.data, env.dt, zero, points[i], points[i + 1], cmd)
                term[i] = bool(task.termination(ctx)) if task.termination else False
                ctx.healthy = not term[i]
                rew[i] = float(env.reward_fn(ctx)[0])
        obs_l.append(obs[:-1])
        nobs_l.append(obs[1:])
        rew_l.append(rew)
        term_l.append(term)
        last = np.zeros(n, dtype=bool)
        last[-1] = True
        last_l.append(last)
    obs = np.concatenate(obs_l)
    n = len(obs)
    terms = np.concatenate(term_l)
    full_info = {
        "task_id": getattr(env, "task_id", None), "dataset_type": "real",
        "obs_names": list(env.obs_spec.names), "simulator": f"mujoco {mujoco.__version__}", "seed": None,
        "policy_checksum": None,
        "reward": ("task reward evaluated on the motion (zero action: motion capture has no actions)" if can_eval
                   else "zeros (motion capture has no reward)"),
        "terminated_fraction": float(terms.mean()) if can_eval else None,
        "retarget_version": RETARGET_VERSION,
        "episode_metrics": [dict(r.metrics) for r in results],
        "episode_sources": [r.source for r in results],
        "episode_returns": [float(x.sum()) for x in rew_l],
    }
    full_info.update(info or {})
    return Trajectories(obs, np.concatenate(nobs_l), None, np.concatenate(rew_l), np.zeros(n, dtype=bool),
                        np.concatenate(last_l), full_info)


def _quality(results: Sequence[Any]) -> dict:
    """Frame-weighted means over episodes (maxima for the max entries)."""
    frames = np.array([r.metrics["frames"] for r in results], dtype=float)
    out = {"frames": int(frames.sum())}
    for k in ("keypoint_error_m", "keypoint_error_uniform_m", "foot_sliding_mps", "penetration_mean_m",
              "in_limits_fraction", "contact_fraction", "root_shift_mean_m"):
        out[k] = float(np.average([r.metrics[k] for r in results], weights=frames))
    for k in ("keypoint_error_max_m", "penetration_max_m"):
        out[k] = float(max(r.metrics[k] for r in results))
    out["seconds"] = float(sum(r.metrics["seconds"] for r in results))
    out["used_keypoints"] = results[0].metrics["used_keypoints"]
    out["dropped_keypoints"] = results[0].metrics["dropped_keypoints"]
    return out


def real_provider(env: Any, *, clips: Optional[Iterable[Any]] = None, options: Any = None,
                  n_episodes: Optional[int] = None, regenerate: bool = False, verbose: bool = True,
                  generation_seed: int = 0, **unused: Any):
    """The `real` dataset of ``env``'s task (full observations) and the episodes' initial states.

    ``clips``: motion files (paths relative to the mocap folder, absolute paths or :class:`ClipSpec`)
    instead of the task's; ``options``: a :class:`~loco_il.motion.mocap.retarget.RetargetOptions`
    (or a dict of its fields); ``n_episodes``: keep the first n clips (a task with a draw gets each clip once per
    version its mode draws from).  ``generation_seed`` is
    accepted and ignored (retargeting is deterministic).
    """

    for name in ("expert", "expert_path", "snapshots"):
        if unused.pop(name, None) is not None:
            raise TypeError(f"a real dataset is built from motion capture; {name}= does not apply")
    if unused:
        raise TypeError(f"unexpected argument(s) for a real dataset: {', '.join(sorted(unused))}")
    task_id = getattr(env, "task_id", "?")
    if not has_robot_map(env.body_name):
        raise ProviderUnavailableError(
            f"{task_id}: real datasets are human motion capture retargeted to the robot, which needs a keypoint "
            f"map of the body; {env.body_name} has none (maps exist for {', '.join(sorted(ROBOT_MAPS))}; add one "
            f"in loco_il/motion/mocap/robot_maps.py)")
    specs = _as_specs(clips, env.task_name, task_id)
    if n_episodes is not None:
        if not 1 <= int(n_episodes) <= len(specs):
            raise ValueError(f"n_episodes must be between 1 and {len(specs)} (the clips kept; one episode per clip, "
                             f"per drawn version for tasks that draw one) for {task_id}")
        specs = specs[:int(n_episodes)]
    if options is None:
        opts = RetargetOptions()
    elif isinstance(options, Mapping):
        opts = RetargetOptions(**options)
    else:
        opts = options
    paths = find_motion_files(specs, what=f"the real dataset of {task_id}")

    key = task_key(env)
    gen_env = generation_env(env, key)
    try:
        if gen_env.draw is not None:     # the motion is retargeted to the draw's reference version
            gen_env.select_draw(gen_env.draw.reference)
        fields = {
            "generator": REAL_GENERATOR_VERSION, "retarget": RETARGET_VERSION, "task": key, "dataset_type": "real",
            "clips": [dict(asdict(s), sha256=file_sha256(p)) for s, p in zip(specs, paths)],
            "options": opts.key(), "model": _model_fingerprint(gen_env.model), "mujoco": mujoco.__version__,
            "map": repr(ROBOT_MAPS[env.body_name]),
        }
        if gen_env.draw is not None:
            fields["draw"] = {"values": list(gen_env.draw.values), "indices": list(gen_env.draw_indices)}
        hkey = cache_key(fields)
        path = datasets_cache_dir() / safe_name(key) / f"real-n{len(specs)}-{hkey}.npz"
        side = init_states_path(path)
        hint = regenerate_hint(path)
        if not regenerate and path.exists() and side.exists():
            data = Trajectories.load(path, regenerate_hint=hint,
                                     expect={"cache_key": hkey, "obs_names": list(gen_env.full_obs_spec.names),
                                             "act_dim": None})
            init = InitStates.load(side, regenerate_hint=hint, n_episodes=data.n_trajectories,
                                   nq=int(gen_env.model.nq), nv=int(gen_env.model.nv))
            return data, init
        if verbose:
            _log(f"[loco_il.datasets] retargeting {len(specs)} motion clip(s) to {key} -> {path}")
        data, init, results = retarget_task(gen_env, specs, paths, opts, verbose=verbose)
        sources = [{"file": p.name, "clip": s.path, "start": s.start, "stop": s.stop, "duration": s.duration,
                    "sha256": f["sha256"], "licence": provenance(p)} for s, p, f in zip(specs, paths, fields["clips"])]
        licences = sorted({s["licence"] for s in sources})
        quality = _quality(results)
        info = dict(data.info)
        info.update(
            task_id=f"{key}.real",
            source=(f"human motion capture ({', '.join(s['file'] for s in sources)}) retargeted to {env.body_name} "
                    f"by loco_il.motion.mocap.retarget v{RETARGET_VERSION}. Licences: " + " | ".join(licences)),
            sources=sources, quality=quality, cache_key=hkey, cache_fields=fields,
            generator=f"loco_il.datasets.real v{REAL_GENERATOR_VERSION}",
            robot_height_m=ROBOT_MAPS[env.body_name].height,
        )
        data = data.replace(info=info)
        if verbose:
            _log(f"[loco_il.datasets] real {key}: {quality['frames']} frames; keypoint error "
                 f"{quality['keypoint_error_m']:.3f} m, foot sliding {quality['foot_sliding_mps']:.3f} m/s, "
                 f"penetration {quality['penetration_mean_m']:.4f} / {quality['penetration_max_m']:.4f} m "
                 f"(mean / max), joints in limits {100 * quality['in_limits_fraction']:.1f}% of frames")
        save_to_cache(path, data, init)   # a cache that cannot be written only warns
        return data, init
    finally:
        gen_env.stop()


def _register() -> None:
    if "real" not in registered_providers():      # a user's provider registered earlier wins
        # quadrupeds get states from the simulated trot generator, humanoids from retargeted mocap
        register_real_provider(real_dispatcher(real_provider))


_register()
