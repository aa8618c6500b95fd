"""Scoring trained policies: returns, normalized scores, trajectory similarity, result tables.

    python -m loco_il.evaluation run_dir=results/InvertedPendulum.balance.perfect/bc/seed0 episodes=10
    python -m loco_il.evaluation record run_dir=... out=video.mp4
    python -m loco_il.evaluation.leaderboard results/

* **Return**: mean ± std over `episodes` evaluation episodes of the deterministic policy (the Gaussian's
  mean), with the task's own reward. Episode i starts from `env.seed(episode_seeds(seed, n)[i]); env.reset()`
  (the seeding of `loco_il.datasets.baselines`), so every evaluation of every run sees the same starts.
* **Normalized score**: `(return - random) / (expert - random)` with the returns recorded in
  `loco_il/datasets/baselines.yaml` (0 = uniform random actions, 1 = the task's shipped expert). When the
  task lacks either part, the score is None and `normalized_score_note` says how to measure it.
* **Trajectory similarity** (discriminator-free) between the states the policy visits and the held-out
  expert states (the dataset's `test` split), both standardized with the expert data's mean and std and
  subsampled to at most `max_points` states each:
  `nn_distance` = mean Euclidean distance from each agent state to its nearest expert state (0 = every
  visited state lies on the expert data), and `mmd` = sqrt of the (biased) squared maximum mean discrepancy
  with a Gaussian kernel whose bandwidth is the median pairwise distance of the pooled states (0 = same
  distribution). `nn_distance_expert` gives the expert's own held-out states' distance to the training
  split, a floor to compare with.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np


# ----------------------------------------------------------------------------- rollouts
def evaluate_policy(env: Any, policy: Callable[[np.ndarray], np.ndarray], episodes: int, seed: int = 1000,
                    collect_obs: bool = False) -> dict[str, Any]:
    """Run `episodes` episodes of `policy` (obs -> action) in `env`; returns, lengths (and visited obs).

    `terminated` counts the episodes that ended in a terminal state before the horizon (on the locomotion
    tasks, a fall), so a low mean can be told apart as a few falls or a worse gait throughout."""
    from loco_il.datasets.providers.expert import episode_seeds
    returns, lengths, observations, starts = [], [], [], []
    terminated = 0
    horizon = int(env.info.horizon)
    for s in episode_seeds(seed, episodes):
        env.seed(int(s))
        obs = env.reset()
        starts.append(np.asarray(obs, dtype=np.float64).tobytes())
        total, t = 0.0, 0
        for t in range(1, horizon + 1):
            if collect_obs:
                observations.append(np.asarray(obs, dtype=np.float64))
            obs, reward, absorbing, _ = env.step(np.asarray(policy(obs), dtype=np.float64))
            total += float(reward)
            if absorbing:
                terminated += 1
                break
        returns.append(total)
        lengths.append(t)
    # episodes are identical only when their starts are too: equal returns from different starts (every
    # episode balancing to the horizon) are distinct episodes, not a sign of a start without reset noise
    outcomes = {(start, round(r, 9), n) for start, r, n in zip(starts, returns, lengths)}
    out = {"returns": returns, "lengths": lengths, "episodes": int(episodes), "eval_seed": int(seed),
           "return_mean": float(np.mean(returns)), "return_std": float(np.std(returns)),
           "length_mean": float(np.mean(lengths)), "terminated": terminated, "distinct_episodes": len(outcomes)}
    if collect_obs:
        out["obs"] = np.asarray(observations)
    return out


def evaluate_agent(agent: Any, env: Any, episodes: int, seed: int = 1000, deterministic: bool = True,
                   collect_obs: bool = False) -> dict[str, Any]:
    """`evaluate_policy` with an `ILAgent` (its deterministic mean action by default); restores its mode."""
    previous = agent.deterministic
    agent.deterministic = bool(deterministic)
    module = getattr(agent, "policy_module", None)
    was_training = module.training if module is not None else None
    if module is not None:
        module.eval()   # normalizers never move during evaluation
    try:
        agent.episode_start()
        return evaluate_policy(env, agent.draw_action, episodes, seed, collect_obs)
    finally:
        agent.deterministic = previous
        if module is not None and was_training:
            module.train()


def evaluate_averaged_actor(agent: Any, env: Any, episodes: int, seed: int = 1000,
                            deterministic: bool = True) -> dict[str, Any] | None:
    """`evaluate_agent` with the moving average of the agent's actor acting (off-policy agents built with
    `actor_ema`), on the same episode seeds; None for an agent that keeps no average."""
    if getattr(agent, "policy_ema", None) is None:
        return None
    with agent.averaged_actor():
        return evaluate_agent(agent, env, episodes, seed, deterministic)


def identical_episodes_note(result: Mapping[str, Any]) -> str | None:
    """A warning when every evaluation episode had the same outcome (deterministic start and policy)."""
    n = int(result.get("episodes") or 0)
    if n > 1 and result.get("distinct_episodes") == 1:
        return (f"all {n} evaluation episodes identical (the env starts without reset noise and the policy is "
                f"deterministic): the std over episodes is 0 by construction; compare over training seeds")
    return None


# ----------------------------------------------------------------------------- scores
def normalized(task_id: str, ret: float) -> tuple[float | None, str | None, dict | None]:
    """(normalized score, note when it cannot be computed, the baseline returns used)."""
    from loco_il.datasets.baselines import BaselineMissingError, get_baseline, normalized_score
    try:
        score = normalized_score(task_id, ret)
        entry = get_baseline(task_id)
        return float(score), None, {"random": float(entry["random"]["return_mean"]),
                                    "expert": float(entry["expert"]["return_mean"])}
    except BaselineMissingError as exc:
        return None, f"no normalized score: {exc}", None
    except ValueError as exc:
        return None, f"no normalized score: {exc}", None


def _standardize(expert: np.ndarray, *others: np.ndarray) -> list[np.ndarray]:
    mean, std = expert.mean(0), expert.std(0)
    std = np.where(std > 1e-8, std, 1.0)
    return [(x - mean) / std for x in (expert, *others)]


def _subsample(x: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    return x if len(x) <= n else x[rng.choice(len(x), size=n, replace=False)]


def _pairwise(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d2 = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.sqrt(np.maximum(d2, 0.0))


def nn_distance(x: np.ndarray, ref: np.ndarray) -> float:
    """Mean over rows of `x` of the Euclidean distance to the nearest row of `ref`."""
    return float(_pairwise(x, ref).min(1).mean())


def mmd(x: np.ndarray, y: np.ndarray) -> float:
    """sqrt of the biased MMD^2 with a Gaussian kernel, bandwidth = median pooled pairwise distance."""
    pooled = np.concatenate([x, y])
    d = _pairwise(pooled, pooled)
    off = d[np.triu_indices(len(pooled), k=1)]
    bw = float(np.median(off)) if off.size and np.median(off) > 0 else 1.0
    k = np.exp(-(d ** 2) / (2.0 * bw ** 2))
    n = len(x)
    value = k[:n, :n].mean() + k[n:, n:].mean() - 2.0 * k[:n, n:].mean()
    return float(math.sqrt(max(value, 0.0)))


def trajectory_similarity(agent_obs: np.ndarray, expert_obs: np.ndarray, expert_train_obs: np.ndarray | None = None,
                          max_points: int = 1000, seed: int = 0) -> dict[str, Any]:
    """Discriminator-free distances between visited and expert states (see the module docstring)."""
    rng = np.random.default_rng(seed)
    agent_obs, expert_obs = np.asarray(agent_obs, np.float64), np.asarray(expert_obs, np.float64)
    if agent_obs.ndim != 2 or expert_obs.ndim != 2 or agent_obs.shape[1] != expert_obs.shape[1]:
        raise ValueError(f"observation arrays differ: {agent_obs.shape} vs {expert_obs.shape}")
    e, a = _standardize(expert_obs, agent_obs)
    e_s, a_s = _subsample(e, max_points, rng), _subsample(a, max_points, rng)
    out = {"nn_distance": nn_distance(a_s, e_s), "mmd": mmd(a_s, e_s), "n_agent_states": int(len(agent_obs)),
           "n_expert_states": int(len(expert_obs)), "max_points": int(max_points)}
    if expert_train_obs is not None and len(expert_train_obs):
        _, tr = _standardize(expert_obs, np.asarray(expert_train_obs, np.float64))
        out["nn_distance_expert"] = nn_distance(e_s, _subsample(tr, max_points, rng))
    return out


# ----------------------------------------------------------------------------- tables
def _fmt(value: Any, digits: int = 4) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.{digits}g}" if abs(value) < 1e4 else f"{value:.1f}"
    return str(value)


def format_eval_table(results: Sequence[Mapping[str, Any]]) -> str:
    """A Markdown table of final evaluations (`eval.json` dicts)."""
    head = ("task", "dataset", "algorithm", "seed", "steps", "episodes", "return (mean ± std)", "normalized",
            "nn_distance", "mmd")
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    for r in results:
        sim = r.get("similarity") or {}
        ret = f"{r['return_mean']:.2f} ± {r['return_std']:.2f}"
        lines.append("| " + " | ".join([r.get("task", "?"), r.get("dataset_type", "?"), r.get("name", "?"),
                                        str(r.get("seed", "?")), _fmt(r.get("steps")), str(r.get("episodes")),
                                        ret, "n/a" if r.get("normalized_score") is None else f"{r['normalized_score']:.3f}",
                                        _fmt(sim.get("nn_distance"), 3),
                                        _fmt(sim.get("mmd"), 3)]) + " |")
    notes = sorted({r["normalized_score_note"] for r in results if r.get("normalized_score_note")}
                   | {note for note in map(identical_episodes_note, results) if note})
    return "\n".join(lines + [f"\nNote: {n}" for n in notes])


# ----------------------------------------------------------------------------- runs on disk
def load_run_config(run_dir: str | Path) -> dict:
    run_dir = Path(run_dir)
    path = run_dir / "config.yaml"
    if not path.is_file():
        raise FileNotFoundError(f"{run_dir} is not a train.py run dir: it has no config.yaml")
    import yaml
    with open(path) as fh:
        return yaml.safe_load(fh)


class RunFileError(ValueError):
    """A run file that cannot be used (damaged, truncated, not a loco_il file): one-line message naming it."""


def load_final_agent(path: str | Path, device: str = "cpu") -> Any:
    """`final_agent.pt`, verified against `final_agent.pt.sha256` when the run recorded one."""
    from loco_il.algorithms.common.agent_base import ILAgent
    from loco_il.utils.hashing import ChecksumMismatchError, verify_sidecar
    try:
        verify_sidecar(path)
        return ILAgent.load(path, device=device)
    except ChecksumMismatchError as exc:
        raise RunFileError(f"{exc}; delete it to score the run's checkpoint.pt instead") from None
    except (OSError, RuntimeError, EOFError, ValueError, KeyError) as exc:
        raise RunFileError(f"cannot read {path} ({type(exc).__name__}: {str(exc).splitlines()[0][:120]}): the file is "
                           f"damaged or truncated; delete it to score the run's checkpoint.pt instead") from None


def load_run_agent(run_dir: str | Path, device: str = "cpu",
                   checkpoint: str | Path | None = None) -> tuple[Any, str]:
    """The trained agent of a run (`final_agent.pt`, else the latest `checkpoint.pt`) and which file it was.
    `checkpoint`: a train.py checkpoint file of this run to load instead (e.g. a copy kept from an earlier step).
    Files with a recorded sha256 are verified first (`RunFileError` / `CheckpointError` naming a damaged one)."""
    import torch

    from loco_il.algorithms import factory
    from loco_il.environments.registry import make
    from loco_il.experiment.checkpoint import has_checkpoint, load_checkpoint, load_run_checkpoint
    run_dir = Path(run_dir)
    if checkpoint is not None:
        ckpt_path = Path(checkpoint)
        if not ckpt_path.is_file():
            raise FileNotFoundError(f"checkpoint {ckpt_path} does not exist")
        ckpt = load_checkpoint(ckpt_path)
    else:
        final = run_dir / "final_agent.pt"
        if final.is_file():
            return load_final_agent(final, device=device), str(final)
        if not has_checkpoint(run_dir):
            raise FileNotFoundError(f"{run_dir} has neither final_agent.pt nor checkpoint.pt (was the run started?)")
        ckpt, ckpt_path = load_run_checkpoint(run_dir, repair=False)
    cfg = load_run_config(run_dir)
    env = make(cfg["task_id"])
    torch.manual_seed(int(cfg.get("seed", 0)))
    agent = factory.build_agent(cfg["algo"]["name"], env.info, cfg["algo"], seed=cfg.get("seed"), device=device)
    agent.load_state_dict(ckpt["agent"])
    env.stop()
    return agent, f"{ckpt_path} (step {ckpt['counters'].get('step')}, training not finished)"


def expert_observations(cfg: Mapping[str, Any], env: Any) -> tuple[np.ndarray | None, np.ndarray | None, str | None]:
    """(held-out expert obs, training expert obs, note) of a run's dataset settings."""
    from loco_il.experiment.runner import load_datasets
    try:
        train, test = load_datasets(env, cfg.get("dataset") or {})
    except Exception as exc:  # noqa: BLE001 - similarity is optional; say why it is missing
        return None, None, f"no trajectory similarity: the dataset could not be loaded ({type(exc).__name__}: {exc})"
    ref = test if test is not None and test.n_transitions else train
    return ref.obs, (train.obs if ref is not train else None), None


def evaluate_run(run_dir: str | Path, episodes: int = 10, seed: int | None = None, similarity: bool = True,
                 max_points: int = 1000, deterministic: bool = True) -> dict[str, Any]:
    """Score a run dir's trained policy; the dict has the keys of the run's `eval.json`."""
    from loco_il.environments.registry import task_key
    from loco_il.environments.registry import make
    cfg = load_run_config(run_dir)
    agent, source = load_run_agent(run_dir)
    env = make(cfg["task_id"])
    ev_cfg = cfg.get("eval") or {}
    seed = int(ev_cfg.get("seed", 1000)) if seed is None else int(seed)
    res = evaluate_agent(agent, env, episodes, seed, deterministic, collect_obs=similarity)
    score, note, base = normalized(cfg["task_id"], res["return_mean"])
    out = {"task_id": env.task_id, "task": task_key(env.task_id) + (".pomdp" if env.task_id.endswith(".pomdp") else ""),
           "dataset_type": env.dataset_type, "algorithm": cfg["algo"]["name"], "name": cfg.get("name"),
           "seed": cfg.get("seed"), "agent_file": source, **{k: v for k, v in res.items() if k != "obs"},
           "normalized_score": score, "normalized_score_note": note, "baseline": base}
    if similarity:
        e_obs, tr_obs, sim_note = expert_observations(cfg, env)
        out["similarity"] = (trajectory_similarity(res["obs"], e_obs, tr_obs, max_points) if e_obs is not None
                             else None)
        if sim_note:
            out["similarity_note"] = sim_note
    env.stop()
    return out


def record_run(run_dir: str | Path, out: str | Path, seed: int = 0, max_steps: int | None = None) -> dict:
    """Write an mp4 of one deterministic episode of a run's policy."""
    from loco_il.environments.registry import make
    from loco_il.environments.rendering import record_episode
    cfg = load_run_config(run_dir)
    agent, source = load_run_agent(run_dir)
    agent.deterministic = True
    agent.policy_module.eval()
    env = make(cfg["task_id"], seed=seed)
    try:
        result = record_episode(env, agent.draw_action, out, max_steps=max_steps)
    finally:
        env.stop()
    result["agent_file"] = source
    return result


def write_json(path: str | Path, data: Mapping[str, Any]) -> None:
    from loco_il.experiment.logging import _jsonable
    from loco_il.utils.atomic import atomic_open
    with atomic_open(path, "w") as fh:
        json.dump(_jsonable(dict(data)), fh, indent=2)
        fh.write("\n")


__all__ = ["evaluate_policy", "evaluate_agent", "identical_episodes_note", "normalized", "trajectory_similarity",
           "nn_distance", "mmd", "format_eval_table", "load_run_config", "load_run_agent", "evaluate_run", "record_run", "write_json"]
