"""Estimated compute of a protocol, in single-core hours, from the costs measured in benchmarks/RESULTS.md.

Per run: training steps x (env step + learner work per step) + evaluations x episodes x horizon x (env step +
action). The per-step figures are the measured ones below (1 torch thread on one core of the 2-core CPU
machine); evaluation episodes are counted at the full horizon (falls end them sooner, so this is an upper
bound). One-off dataset generation is not counted (datasets are cached).
Training logs of runs side by side on the 2-core machine (benchmarks/il_results/long_runs) ran the SAC-based
learners at 1.0-1.3x these per-step times on Hopper and ~2x on Ant and Humanoid.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

from loco_il.benchmark.cells import Cell
from loco_il.benchmark.protocol import Protocol

#: env steps/s of each body on one core: RESULTS.md "Environment step overhead and creation time"
#: (benchmarks/env_step.py --steps 1000 --blocks 3, the 2-core CPU machine)
ENV_STEPS_PER_S: dict[str, float] = {
    "Ant": 1954, "ApptronikApollo": 4542, "Atlas": 595, "BerkeleyHumanoid": 3315, "BoosterT1": 2358, "G1": 1427,
    "H1": 2943, "HalfCheetah": 10200, "Hopper": 5006, "Humanoid": 2232, "HumanoidMuscle": 959,
    "HumanoidStandup": 1245, "HumanoidTorque": 661, "InvertedPendulum": 14613, "MyoLeg": 1181,
    "RobotisOP3": 2860, "Talos": 1605, "UnitreeA1": 988, "UnitreeG1": 750, "UnitreeGo1": 1891, "UnitreeH1": 1849,
    "Walker2d": 3389,
}

#: learner work per training step, ms (RESULTS.md "Imitation-learning agents: update and on-policy speed"):
#: on-policy: TRPO fit per env step (409-439 us) + draw_action (20 us); SAC-based: one update per env step
#: (il_speed.py, run 2) + 0.4 ms for acting and storing the transition (an LS-IQ run on Hopper: 78 env steps/s,
#: i.e. 12.8 ms per step, against a 12.2 ms update and a 0.2 ms env step); BC: one gradient step, from the
#: leaderboard's own runs (benchmarks/cost_model_check.py: 100,000 gradient steps and 60 evaluation episodes in
#: 383-413 s on HalfCheetah, Ant and Humanoid, whose evaluations take 6-29 s of it).
LEARNER_MS: dict[str, float] = {
    "gail": 0.46, "vail": 0.46, "gaifo": 0.46,
    "iqlearn": 18.79 + 0.4, "lsiq": 12.20 + 0.4, "lsiqfo": 14.64 + 0.4, "sqil": 16.39 + 0.4,
    "bc": 3.8,
}
#: the default number of critics of each SAC-based learner (experiment_configs/algo/)
DEFAULT_CRITICS = {"iqlearn": 2, "lsiq": 1, "lsiqfo": 1, "sqil": 2}
#: a twin-critic SAC update over a one-critic one: il_speed.py "bare SAC" 16.18 ms / "bare SAC 1Q" 10.58 ms
TWIN_CRITIC_FACTOR = 16.18 / 10.58
#: the LayerNorm critic's cost per update: 3-17 % in 8 measured ratios (il_speed.py --critic-layer-norm)
LAYER_NORM_FACTOR = 1.10
#: time to choose an action in an evaluation episode, ms: on-policy and BC policies (numpy, 20 us), SAC actors
ACT_MS = {"sac": 0.4, "other": 0.02}
HORIZON = 1000          # every task of the grids (LocoMuJoCo's and Gymnasium's horizon)


class CostError(KeyError):
    """A body or learner without a measured cost: one line naming it and where to add one."""

    def __str__(self) -> str:
        return str(self.args[0])


def body_of(task_id: str) -> str:
    return task_id.split(".", 1)[0].split("-", 1)[0]


def learner_ms(algo: str, overrides: Sequence[tuple[str, Any]] = ()) -> float:
    """Learner work per step, adjusted for a variant's critic count and LayerNorm."""
    if algo not in LEARNER_MS:
        raise CostError(f"no measured cost for algorithm {algo!r}; add it to LEARNER_MS in {__name__} "
                        f"(benchmarks/il_speed.py measures it)")
    ms = LEARNER_MS[algo]
    settings = dict(overrides)
    critics = settings.get("algo.params.n_critics")
    if critics is not None and algo in DEFAULT_CRITICS and int(critics) != DEFAULT_CRITICS[algo]:
        ms *= TWIN_CRITIC_FACTOR if int(critics) > DEFAULT_CRITICS[algo] else 1.0 / TWIN_CRITIC_FACTOR
    if settings.get("algo.params.critic_layer_norm") is True:
        ms *= LAYER_NORM_FACTOR
    return ms


def env_ms(task_id: str) -> float:
    body = body_of(task_id)
    if body not in ENV_STEPS_PER_S:
        raise CostError(f"no measured env speed for body {body!r}; add it to ENV_STEPS_PER_S in {__name__} "
                        f"(`python benchmarks/env_step.py` measures it)")
    return 1000.0 / ENV_STEPS_PER_S[body]


def run_hours(proto: Protocol, cell: Cell) -> float:
    """Estimated single-core hours of one run of a cell."""
    ev: Mapping[str, Any] = dict(proto.eval)
    step_env = env_ms(cell.task_id)
    online = cell.family.unit == "env"
    train_ms = cell.budget * (learner_ms(cell.algo, cell.overrides) + (step_env if online else 0.0))
    act = ACT_MS["sac" if cell.algo in DEFAULT_CRITICS else "other"]
    n_evals = math.ceil(cell.budget / cell.family.eval_every)
    episodes = n_evals * int(ev.get("episodes", 5)) + int(ev.get("final_episodes", 10))
    eval_ms = episodes * HORIZON * (step_env + act)
    return (train_ms + eval_ms) / 3.6e6


@dataclass(frozen=True)
class PartCost:
    part: str
    runs: int
    hours: float


def estimate(proto: Protocol, cells: Sequence[Cell]) -> list[PartCost]:
    """Single-core hours per part (the protocol's order), every seed of every given cell counted."""
    out: dict[str, list[float]] = {p.name: [0, 0.0] for p in proto.parts}
    for cell in cells:
        out[cell.part][0] += len(cell.seeds)
        out[cell.part][1] += len(cell.seeds) * run_hours(proto, cell)
    return [PartCost(name, int(n), h) for name, (n, h) in out.items() if n]


def hours_text(h: float) -> str:
    """Hours to two significant digits below 10, whole hours above."""
    return f"{h:.0f}" if h >= 10 else f"{h:.2g}"


def format_estimate(costs: Sequence[PartCost], jobs: int = 2) -> str:
    """The estimate as text lines (for the CLI, the protocol's comments and the table)."""
    total = sum(c.hours for c in costs)
    lines = [f"part {c.part}: {c.runs} runs, {hours_text(c.hours)} single-core hours" for c in costs]
    lines.append(f"total: {sum(c.runs for c in costs)} runs, {hours_text(total)} single-core hours")
    lines.append(f"with {jobs} runs at a time: ~{total / jobs / 24:.1f} days at these rates, up to "
                 f"~{2 * total / jobs / 24:.1f} days where runs side by side slow each other")
    return "\n".join(lines)


def summary_text(proto: Protocol, cells: Sequence[Cell], jobs: int = 2) -> str:
    """The estimate of `cells`, and the part of it that waits for a dataset (the text in the protocol files'
    comments and in the table)."""
    from loco_il.benchmark.availability import blocked_reason
    text = format_estimate(estimate(proto, cells), jobs)
    blocked = [c for c in cells if blocked_reason(c.task_id)]
    if blocked:
        hours = sum(run_hours(proto, c) * len(c.seeds) for c in blocked)
        runs = sum(len(c.seeds) for c in blocked)
        tasks = ", ".join(sorted({c.task_id for c in blocked}))
        text += f"\nof these, blocked until their dataset exists: {runs} runs, {hours_text(hours)} hours ({tasks})"
    return text


__all__ = ["estimate", "format_estimate", "summary_text", "run_hours", "hours_text", "PartCost", "CostError",
           "ENV_STEPS_PER_S", "LEARNER_MS"]
