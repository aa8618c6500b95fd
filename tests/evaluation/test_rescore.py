"""`python -m loco_il.evaluation.rescore`: runs logged before their task's baseline existed get their normalized
scores from the returns they logged; nothing else in their files changes."""
from __future__ import annotations

import csv
import json

from loco_il.datasets.baselines import get_baseline
from loco_il.evaluation import rescore
from loco_il.experiment.logging import CSV_COLUMNS


def _run(run_dir, task_id, returns, final, score=None):
    run_dir.mkdir(parents=True)
    (run_dir / "eval.json").write_text(json.dumps({"task_id": task_id, "seed": 0, "return_mean": final,
                                                   "normalized_score": score, "baseline": None,
                                                   "normalized_score_note": "no normalized score: no baseline"}))
    with open(run_dir / "log.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_COLUMNS)
        w.writeheader()
        for i, r in enumerate(returns):
            w.writerow({"step": 100 * (i + 1), "train_return": 1.5, "eval_return_mean": "" if r is None else r,
                        "normalized_score": ""})


def test_rescore_fills_the_normalized_scores_from_the_logged_returns(tmp_path, capsys):
    base = get_baseline("Hopper.run")
    rnd, exp = base["random"]["return_mean"], base["expert"]["return_mean"]
    hop, other = tmp_path / "Hopper.run.perfect" / "gail" / "seed0", tmp_path / "UnitreeH1.run.real" / "gail" / "seed0"
    _run(hop, "Hopper.run.perfect", [100.0, None, 2000.0], 2000.0)
    _run(other, "UnitreeH1.run.real", [5.0], 5.0)
    log_before = (hop / "log.csv").read_bytes()
    assert rescore.main([str(tmp_path)]) == 0
    assert "1 of 2 run(s) re-scored" in capsys.readouterr().out
    ev = json.loads((hop / "eval.json").read_text())
    assert abs(ev["normalized_score"] - (2000.0 - rnd) / (exp - rnd)) < 1e-9
    assert ev["baseline"] == {"random": rnd, "expert": exp} and ev["normalized_score_note"] is None
    rows = list(csv.DictReader(open(hop / "log.csv", newline="")))
    assert abs(float(rows[0]["normalized_score"]) - (100.0 - rnd) / (exp - rnd)) < 1e-9
    assert rows[1]["normalized_score"] == "" and rows[2]["train_return"] == "1.5"
    # the rewritten log keeps the logger's line ends; only the normalized column changed
    after = (hop / "log.csv").read_bytes()
    assert after.count(b"\r\n") == log_before.count(b"\r\n") and after.split(b"\r\n")[0] == log_before.split(b"\r\n")[0]
    # the task without a baseline is untouched; a second pass changes nothing
    assert json.loads((other / "eval.json").read_text())["normalized_score"] is None
    assert rescore.main([str(tmp_path)]) == 0 and "0 of 2 run(s) re-scored" in capsys.readouterr().out


def test_rescore_refuses_a_missing_path_and_a_foreign_log(tmp_path, capsys):
    assert rescore.main([str(tmp_path / "nope")]) == 2
    assert "no such run dir or folder" in capsys.readouterr().err
    run = tmp_path / "run"
    _run(run, "Hopper.run.perfect", [100.0], 100.0)
    (run / "log.csv").write_text("step,return\n1,2\n")
    assert rescore.main([str(run)]) == 2
    assert "are not a train.py log.csv's" in capsys.readouterr().err
    assert (run / "log.csv").read_text() == "step,return\n1,2\n"
    assert json.loads((run / "eval.json").read_text())["normalized_score"] is None
