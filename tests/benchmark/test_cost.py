"""The cost estimate: the arithmetic on RESULTS.md's per-step costs, and the figures written in the shipped protocols'
comments match what `python -m loco_il.benchmark cost` computes now."""
from __future__ import annotations

import pytest

from loco_il.benchmark import cost
from loco_il.benchmark.cells import select
from loco_il.benchmark.protocol import load_protocol, protocol_path


@pytest.mark.parametrize("name", ["small", "paper"])
def test_protocol_comments_hold_the_current_estimate(name):
    proto = load_protocol(name)
    lines = protocol_path(name).read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("# Estimated cost"))
    written = [line[len("#   "):] for line in lines[start + 1:] if line.startswith("#   ")]
    assert written == cost.summary_text(proto, select(proto)).splitlines()


def test_run_hours_of_one_cell():
    proto = load_protocol("small")
    cell = next(c for c in select(proto) if c.key == "Hopper.run.perfect/gail")
    env_ms = 1000 / cost.ENV_STEPS_PER_S["Hopper"]
    train = 1_000_000 * (0.46 + env_ms)
    evals = (20 * 5 + 10) * 1000 * (env_ms + 0.02)       # 20 evaluations of 5 episodes, 10 final episodes
    assert cost.run_hours(proto, cell) == pytest.approx((train + evals) / 3.6e6)


def test_variant_costs_follow_its_critics_and_layer_norm():
    base = cost.learner_ms("lsiq")
    held = cost.learner_ms("lsiq", [("algo.params.n_critics", 2), ("algo.params.critic_layer_norm", True)])
    assert held == pytest.approx(base * cost.TWIN_CRITIC_FACTOR * cost.LAYER_NORM_FACTOR)
    assert cost.learner_ms("sqil", [("algo.params.n_critics", 1)]) == pytest.approx(
        cost.learner_ms("sqil") / cost.TWIN_CRITIC_FACTOR)


def test_unmeasured_body_or_learner_names_where_to_add_it():
    with pytest.raises(cost.CostError, match="no measured env speed for body 'Robot'.*env_step.py"):
        cost.env_ms("Robot.walk.real")
    with pytest.raises(cost.CostError, match="no measured cost for algorithm 'ppo'"):
        cost.learner_ms("ppo")
