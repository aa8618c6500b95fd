"""The cost estimate: the arithmetic on RESULTS.md's per-step costs, the figures written in the shipped protocols'
comments match what `python -m loco_il.benchmark cost` computes now, and the check of the estimate against finished
runs (`cost_check`, RESULTS.md's block of it)."""
from __future__ import annotations

import pytest
from script_loader import load_script

from loco_il.benchmark import cost, cost_check, doc_block, paths
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


def test_cost_check_sets_the_model_against_finished_cpu_runs(grid):
    """Only finished runs with a wall time trained on the CPU count: Hopper gail seeds 0-1 (seed 2 trained on cuda;
    the bc runs and the UnitreeH1 run recorded no wall time, the vail run has another budget)."""
    path, logs, _ = grid
    proto = load_protocol(path)
    rows = cost_check.rows(proto, logs)
    assert [(r.key, r.walls) for r in rows] == [("Hopper.run.perfect/gail", (1200.4, 1310.6))]
    model_s = cost.run_hours(proto, next(c for c in select(proto) if c.key == "Hopper.run.perfect/gail")) * 3600
    assert rows[0].ratio == pytest.approx((1200.4 + 1310.6) / 2 / model_s)
    lines = cost_check.report(proto, logs)
    assert lines[1].split()[-1] == f"{rows[0].ratio:.2f}"
    assert lines[-1] == f"onpolicy: median ratio {rows[0].ratio:.2f} over 1 cells " \
                        f"(range {rows[0].ratio:.2f}-{rows[0].ratio:.2f})"


def test_cost_check_script_writes_its_block_or_names_the_missing_markers(grid, capsys):
    path, logs, _ = grid
    script = load_script("cost_model_check")
    doc = path.parent / "RESULTS.md"
    doc.write_text("# Results\n<!-- cost-model-check:tiny -->\nold\n<!-- /cost-model-check:tiny -->\nReading.\n")
    assert script.main(["--protocol", str(path), "--results-dir", str(logs), "--results", str(doc)]) == 0
    report = cost_check.report(load_protocol(path), logs)
    assert doc.read_text() == "# Results\n<!-- cost-model-check:tiny -->\n" + "\n".join(["```", *report, "```"]) \
        + "\n<!-- /cost-model-check:tiny -->\nReading.\n"
    doc.write_text("# Results\n")
    assert script.main(["--protocol", str(path), "--results-dir", str(logs), "--results", str(doc)]) == 2
    assert "has no '<!-- cost-model-check:tiny -->' ... '<!-- /cost-model-check:tiny -->' block" \
        in capsys.readouterr().out
    assert doc.read_text() == "# Results\n"


def test_the_results_page_holds_the_cost_check_the_committed_logs_give():
    """Adding runs to benchmarks/leaderboard/logs/ without rewriting RESULTS.md's cost model check fails here."""
    results = paths.ROOT / "benchmarks" / "RESULTS.md"
    text = results.read_text()
    fresh = doc_block.replace_block(text, cost_check.block_name("small"),
                                    cost_check.fenced(cost_check.report(load_protocol("small"))))
    assert fresh == text, ("stale cost model check: "
                           "python benchmarks/cost_model_check.py --protocol small --results benchmarks/RESULTS.md")
