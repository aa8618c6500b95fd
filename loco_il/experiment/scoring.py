"""Scoring a policy: evaluation rollouts, normalized scores, trajectory similarity, result tables.

* **Return**: mean ± std over `episodes` evaluation episodes of the deterministic policy (the Gaussian's
  mean), with the task's own reward. Episode i starts from `env.seed(episode_seeds(seed, n)[i]); env.reset()`
  (the seeding of the datasets and `loco_il.datasets.baselines`; the loop of `loco_il.environments.episodes`),
  so every evaluation of every run sees the same starts.
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

import math
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from loco_il.environments.episodes import episode_seeds, outcome_arrays, run_episodes


# ----------------------------------------------------------------------------- rollouts
def evaluate_policy(env: Any, policy: Callable[[np.ndarray], np.ndarray], episodes: int, seed: int = 1000,
                    collect_obs: bool = False) -> dict[str, Any]:
    """Run `episodes` episodes of `policy` (obs -> action) in `env` (`loco_il.environments.episodes.run_episode`);
    returns, lengths (and visited obs).

    `terminated` counts the episodes that ended in a terminal state before the horizon (on the locomotion
    tasks, a fall), so a low mean can be told apart as a few falls or a worse gait throughout."""
    runs = run_episodes(env, policy, episode_seeds(seed, episodes), int(env.info.horizon), record=collect_obs)
    returns, lengths, terminated = outcome_arrays([ep.outcome for ep in runs])
    # episodes are identical only when their starts are too: equal returns from different starts (every
    # episode balancing to the horizon) are distinct episodes, not a sign of a start without reset noise
    outcomes = {(ep.start_obs.tobytes(), round(ep.ret, 9), ep.length) for ep in runs}
    out = {"returns": returns.tolist(), "lengths": lengths.tolist(), "episodes": int(episodes),
           "eval_seed": int(seed), "return_mean": float(np.mean(returns)), "return_std": float(np.std(returns)),
           "length_mean": float(np.mean(lengths)), "terminated": int(terminated.sum()),
           "distinct_episodes": len(outcomes)}
    if collect_obs:
        out["obs"] = np.concatenate([ep.obs for ep in runs])
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


__all__ = ["evaluate_policy", "evaluate_agent", "evaluate_averaged_actor", "identical_episodes_note", "normalized",
           "trajectory_similarity", "nn_distance", "mmd", "format_eval_table"]
