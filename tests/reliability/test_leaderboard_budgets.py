"""Item 8: runs of different budgets are separate leaderboard rows, each showing its budget."""
from __future__ import annotations

import json

from loco_il.evaluation import leaderboard


def test_runs_of_different_budgets_are_not_pooled(tmp_path):
    for seed, steps, ret in ((0, 0, 5.0), (1, 2000, 1000.0), (2, 2000, 900.0)):
        d = tmp_path / f"seed{seed}"
        d.mkdir()
        (d / "eval.json").write_text(json.dumps({
            "task": "InvertedPendulum.balance", "dataset_type": "perfect", "algorithm": "bc", "name": "bc",
            "seed": seed, "steps": steps, "step_unit": "gradient steps", "return_mean": ret}))
    res = leaderboard.build(tmp_path, plots=False)
    rows = [(r["budget"], r["n_seeds"], r["return_mean"]) for r in res["rows"]]
    assert rows == [("0 gradient steps", 1, 5.0), ("2000 gradient steps", 2, 950.0)]
    assert "| InvertedPendulum.balance | perfect | bc | 0 gradient steps | 1 | 5.00 |" in res["markdown"]
    assert "| InvertedPendulum.balance | perfect | bc | 2000 gradient steps | 2 | 950.00 ± " in res["markdown"]
    assert "InvertedPendulum.balance,perfect,bc,2000 gradient steps,2,1 2,950.0000," in res["csv"]
