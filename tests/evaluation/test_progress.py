"""`python -m loco_il.evaluation.progress`: where finished and unfinished runs stand, from config.yaml + log.csv."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import yaml

from loco_il.evaluation import progress
from loco_il.experiment.logging import CSV_COLUMNS


def make_run(root: Path, algo: str, budget: int, rows: list[tuple],
             finished: bool = False, seed: int = 0) -> Path:
    """A run dir as train.py leaves it; rows = (step, steps/s, eval return, normalized score[, episodes that
    ended in a terminal state, of 5]); a row without the fifth entry leaves the column empty (older logs)."""
    run = root / "Hopper.run.perfect" / algo / f"seed{seed}"
    (run / ".hydra").mkdir(parents=True)
    cfg = {"task_id": "Hopper.run.perfect", "name": algo, "seed": seed, "n_steps": budget}
    (run / "config.yaml").write_text(yaml.safe_dump(cfg))
    (run / ".hydra" / "config.yaml").write_text("task_id: ${hydra:runtime.choices.task}\nn_steps: 1\n")
    with open(run / "log.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_COLUMNS, extrasaction="ignore")
        w.writeheader()
        for step, sps, ret, norm, *fell in rows:
            w.writerow({"step": step, "env_steps": step, "steps_per_s": sps, "eval_return_mean": ret,
                        "normalized_score": norm, "eval_episodes": 5, "eval_terminated": fell[0] if fell else ""})
    if finished:
        (run / "eval.json").write_text(json.dumps({"return_mean": rows[-1][2]}))
    return run


def test_progress_of_finished_unfinished_and_fresh_runs(tmp_path, capsys):
    make_run(tmp_path, "lsiq", 1_500_000, [(50_000, 40.0, 900.0, 0.27), (100_000, 36.0, 1200.0, 0.37)])
    make_run(tmp_path, "gail", 100_000, [(100_000, 1000.0, 3000.0, 0.93)], finished=True)
    make_run(tmp_path, "sqil", 1_000_000, [])
    rows = {r["algorithm"]: r for r in progress.collect_progress(tmp_path)}
    assert set(rows) == {"lsiq", "gail", "sqil"}           # Hydra's unresolved .hydra/config.yaml is not a run
    lsiq = rows["lsiq"]
    assert (lsiq["step"], lsiq["return"], lsiq["normalized"], lsiq["state"]) == (100_000, 1200.0, 0.37, "unfinished")
    assert abs(lsiq["done"] - 100_000 / 1_500_000) < 1e-12
    assert abs(lsiq["rest_hours"] - 1_400_000 / 36.0 / 3600.0) < 1e-9   # the last interval's speed
    assert rows["gail"]["state"] == "finished" and rows["gail"]["rest_hours"] is None
    assert rows["sqil"]["state"] == "no evaluation yet" and rows["sqil"]["step"] == 0

    assert progress.main([str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "| Hopper.run.perfect | lsiq | 0 | 100000 | 1500000 | 6.7 | 1200.0 | 0.370 | 36.0 | 10.8 | n/a | unfinished |" in out


def test_progress_names_the_step_a_killed_run_resumes_from(tmp_path, capsys):
    """A run killed 25k after its last checkpoint: the table says it resumes at the checkpoint, not at the last
    evaluation; an unreadable checkpoint.json reads as unknown instead of failing the table."""
    run = make_run(tmp_path, "lsiq", 1_500_000, [(225_000, 25.0, 5000.0, 0.79), (245_000, 25.0, 6000.0, 1.0)])
    (run / "checkpoint.json").write_text(json.dumps({"step": 225_000, "env_steps": 225_000, "finished": False}))
    assert progress.run_progress(run)["resume_step"] == 225_000
    assert progress.main([str(tmp_path)]) == 0
    assert "| 245000 | 1500000 | 16.3 | 6000.0 | 1.000 | 25.0 | 13.9 | 225000 | unfinished |" in capsys.readouterr().out
    (run / "checkpoint.json").write_text('{"step": 2250')   # e.g. a copy cut short
    assert progress.run_progress(run)["resume_step"] is None


def test_progress_cli_errors(tmp_path, capsys):
    assert progress.main([str(tmp_path / "missing")]) == 2
    assert "is not a folder" in capsys.readouterr().err
    assert progress.main([str(tmp_path)]) == 1
    assert "no train.py run dirs" in capsys.readouterr().err


def test_progress_curves(tmp_path, capsys):
    make_run(tmp_path, "lsiq", 1_500_000, [(25_000, 90.0, 1100.0, 0.334), (50_000, 95.0, 1300.0, 0.396),
                                           (1_500_000, 95.0, 3000.0, None)])
    make_run(tmp_path, "sqil", 1_000_000, [])
    assert progress.main([str(tmp_path), "--curves"]) == 0
    out = capsys.readouterr().out
    assert "Hopper.run.perfect lsiq seed 0: 25k:0.33 50k:0.40 1500k:n/a" in out
    assert "Hopper.run.perfect sqil seed 0: no evaluation yet" in out
    assert progress.main([str(tmp_path)]) == 0
    assert "normalized score at each evaluation" not in capsys.readouterr().out


def test_stability_after_first_reaching_the_threshold():
    curve = [(25_000, 0.3), (50_000, 0.95), (75_000, 0.5), (100_000, None), (125_000, 0.92), (150_000, 0.7)]
    st = progress.stability(curve, 0.9)
    assert st["reached"] == 50_000 and st["n_after"] == 3          # the unscored evaluation is left out
    assert abs(st["share_after"] - 1 / 3) < 1e-12
    assert st["min_after"] == 0.5 and abs(st["mean_after"] - (0.5 + 0.92 + 0.7) / 3) < 1e-12
    assert progress.stability(curve, 0.99)["reached"] is None
    last = progress.stability([(25_000, 0.2), (50_000, 0.97)], 0.9)
    assert last["reached"] == 50_000 and last["n_after"] == 0 and last["share_after"] is None


def test_stability_counts_the_dips_that_had_a_fall():
    """Of the evaluations below the threshold after reaching it, those with a terminal episode; dips without a
    logged count (older logs) and the evaluations before reaching it are not counted."""
    curve = [(5_000, 0.2), (10_000, 0.95), (15_000, 0.6), (20_000, 0.85), (25_000, 0.93), (30_000, 0.7)]
    terminated = {5_000: (5, 5), 10_000: (0, 5), 15_000: (2, 5), 20_000: (0, 5), 25_000: (1, 5)}
    st = progress.stability(curve, 0.9, terminated)
    assert (st["n_dips"], st["n_dips_logged"], st["n_dips_with_fall"]) == (3, 2, 1)
    assert (st["dip_episodes_fell"], st["dip_episodes"]) == (2, 10)
    assert progress.stability(curve, 0.9)["n_dips_logged"] == 0


def test_progress_stability_cli(tmp_path, capsys):
    make_run(tmp_path, "lsiq", 1_500_000, [(25_000, 90.0, 1100.0, 0.3, 5), (50_000, 95.0, 3200.0, 0.98, 0),
                                           (75_000, 95.0, 1500.0, 0.665, 3), (100_000, 95.0, 3250.0, 0.99, 0)])
    make_run(tmp_path, "sqil", 1_000_000, [(25_000, 90.0, 900.0, 0.25)])
    assert progress.main([str(tmp_path), "--stability", "0.9"]) == 0
    out = capsys.readouterr().out
    # three decimals for the minimum: 0.665 must not read as 0.67 (nor 0.899 as >= 0.9)
    assert ("Hopper.run.perfect lsiq seed 0: >= 0.9 first at 50k; after it 2 evaluations, 50 % >= 0.9, "
            "min 0.665, mean 0.83; of the 1 below it, 1 had an episode end in a fall (3 of 5 episodes)\n") in out
    assert "Hopper.run.perfect sqil seed 0: never >= 0.9" in out


def test_runs_with_an_actor_average_get_a_second_curve_and_stability_line(tmp_path, capsys):
    run = make_run(tmp_path, "lsiq", 1_500_000, [(25_000, 90.0, 3000.0, 0.95), (50_000, 90.0, 1500.0, 0.45),
                                                 (75_000, 90.0, 3100.0, 0.97)])
    make_run(tmp_path, "sqil", 1_000_000, [(25_000, 90.0, 900.0, 0.3)])
    with open(run / "log.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    for row, ema in zip(rows, (0.5, 0.93, 0.96)):
        row["normalized_score_ema"] = ema
    with open(run / "log.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_COLUMNS)
        w.writeheader()
        w.writerows(rows)
    assert progress.main([str(tmp_path), "--curves", "--stability", "0.9"]) == 0
    out = capsys.readouterr().out
    assert "Hopper.run.perfect lsiq seed 0: 25k:0.95 50k:0.45 75k:0.97" in out
    assert "Hopper.run.perfect lsiq seed 0 (actor average): 25k:0.50 50k:0.93 75k:0.96" in out
    assert "lsiq seed 0 (actor average): >= 0.9 first at 50k; after it 1 evaluations, 100 % >= 0.9" in out
    assert "lsiq seed 0: >= 0.9 first at 25k; after it 2 evaluations, 50 % >= 0.9, min 0.450" in out
    assert "sqil seed 0 (actor average)" not in out          # runs without an average: one line each


def test_upto_compares_runs_over_the_same_env_steps(tmp_path, capsys):
    """--upto cuts the curves, the stability lines and their fall counts at a step; a run that never gets there is
    given its best score (the first step at it) and, where the log counts them, its falls."""
    make_run(tmp_path, "lsiq", 1_500_000, [(25_000, 90.0, 1100.0, 0.3, 5), (50_000, 95.0, 1500.0, 0.45, 2),
                                           (75_000, 95.0, 1500.0, 0.45, 1), (100_000, 95.0, 3250.0, 0.99, 0)])
    assert progress.main([str(tmp_path), "--curves", "--stability", "0.9", "--upto", "75000"]) == 0
    out = capsys.readouterr().out
    assert "normalized score at each evaluation (evaluations up to 75k):\nHopper.run.perfect lsiq seed 0: " \
           "25k:0.30 50k:0.45 75k:0.45\n" in out
    assert ("Hopper.run.perfect lsiq seed 0: never >= 0.9 (best 0.450 at 50k); 3 of its 3 evaluations had an "
            "episode end in a fall (8 of 15 episodes)\n") in out
    assert "| Hopper.run.perfect | lsiq | 0 | 100000 |" in out      # the table still shows where the run is
    assert progress.main([str(tmp_path), "--stability", "0.9"]) == 0
    assert "lsiq seed 0: >= 0.9 first at 100k; after it 0 evaluations" in capsys.readouterr().out


def test_every_reads_a_run_on_a_coarser_evaluation_grid(tmp_path, capsys):
    """--every keeps only the evaluations at multiples of a step (a 5k-evaluated run read on a 25k grid): the dips
    between the grid points and their falls leave the curve and the stability line; it combines with --upto."""
    make_run(tmp_path, "sqil", 1_500_000, [(20_000, 1, 0, 0.4, 5), (25_000, 1, 0, 0.95, 0), (30_000, 1, 0, 0.5, 3),
                                           (45_000, 1, 0, 0.6, 2), (50_000, 1, 0, 0.97, 0), (75_000, 1, 0, 0.73, 1)])
    assert progress.main([str(tmp_path), "--curves", "--stability", "0.9", "--every", "25000"]) == 0
    out = capsys.readouterr().out
    assert "normalized score at each evaluation (evaluations every 25k):\nHopper.run.perfect sqil seed 0: " \
           "25k:0.95 50k:0.97 75k:0.73\n" in out
    assert ("sqil seed 0: >= 0.9 first at 25k; after it 2 evaluations, 50 % >= 0.9, min 0.730, mean 0.85; of the 1 "
            "below it, 1 had an episode end in a fall (1 of 5 episodes)") in out
    assert progress.main([str(tmp_path), "--stability", "0.9", "--every", "25000", "--upto", "50000"]) == 0
    out = capsys.readouterr().out
    assert "does it stay? (evaluations every 25k up to 50k)" in out
    assert "sqil seed 0: >= 0.9 first at 25k; after it 1 evaluations, 100 % >= 0.9" in out
    assert progress.main([str(tmp_path), "--stability", "0.9"]) == 0      # all of them: the dips count
    assert "after it 4 evaluations, 25 % >= 0.9" in capsys.readouterr().out


def test_every_rejects_a_step_that_is_not_positive(tmp_path, capsys):
    make_run(tmp_path, "sqil", 1_500_000, [(25_000, 1, 0, 0.95)])
    with pytest.raises(SystemExit) as stop:
        progress.main([str(tmp_path), "--every", "0"])
    assert stop.value.code == 2
    assert "--every must be a positive number of env steps, got 0" in capsys.readouterr().err


def test_seeds_of_a_setting_are_summarized_together(tmp_path, capsys):
    """--stability adds one line per task and algorithm with several seeds: the held evaluations pooled over the
    seeds (each counted after its own first >= threshold), the last 50k env steps of each seed, and the best score
    of a setting that never got there; a setting with one seed gets no such line."""
    make_run(tmp_path, "lsiq", 1_500_000, [(50_000, 1, 0, 0.95), (100_000, 1, 0, 0.5), (150_000, 1, 0, 0.92),
                                           (200_000, 1, 0, 0.91)], seed=1)
    make_run(tmp_path, "lsiq", 1_500_000, [(50_000, 1, 0, 0.2), (100_000, 1, 0, 0.2), (150_000, 1, 0, 0.93),
                                           (160_000, 1, 0, 0.899), (170_000, 1, 0, None)], seed=2)
    make_run(tmp_path, "sqil", 1_500_000, [(50_000, 1, 0, 0.3), (100_000, 1, 0, 0.45)], seed=1)
    make_run(tmp_path, "sqil", 1_500_000, [(50_000, 1, 0, 0.41)], seed=2)
    make_run(tmp_path, "gail", 1_500_000, [(50_000, 1, 0, 0.99)], seed=1)
    rows = [r for r in progress.collect_progress(tmp_path) if r["algorithm"] == "lsiq"]
    sm = progress.summarize_seeds(rows, 0.9)
    # seed 1: after 50k, 2 of 3 held; seed 2: after 150k, 0 of 1 (the unscored 170k is left out)
    assert (sm["reached"], sm["n_after"], sm["n_held"]) == ([50_000, 150_000], 4, 2)
    # last 50k, after each seed's last scored step - 50k: seed 1's 200k (0.91), seed 2's 150k (0.93) and 160k (0.899)
    assert (sm["n_last"], sm["n_last_held"], sm["last_steps"]) == (3, 2, (160_000, 200_000))

    assert progress.main([str(tmp_path), "--stability", "0.9"]) == 0
    out = capsys.readouterr().out
    assert ("Hopper.run.perfect lsiq, 2 seeds to 160k-200k: 2 reached >= 0.9 (first at 50k-150k); held 2/4 (50 %); "
            "last 50k of each: 2/3 >= 0.9\n") in out
    assert "Hopper.run.perfect sqil, 2 seeds to 50k-100k: none reached >= 0.9 (best 0.450)\n" in out
    assert "gail, " not in out
    assert progress.main([str(tmp_path), "--stability", "0.9", "--upto", "100000"]) == 0
    out = capsys.readouterr().out
    assert "over the seeds of each setting (evaluations up to 100k; held:" in out
    assert ("Hopper.run.perfect lsiq, 2 seeds to 100k: 1 reached >= 0.9 (first at 50k); held 0/1 (0 %); "
            "last 50k of each: 0/2 >= 0.9") in out
    # the same seed twice below the root (a run dir and its copy) is not counted twice
    make_run(tmp_path / "copy", "lsiq", 1_500_000, [(50_000, 1, 0, 0.95)], seed=1)
    assert progress.main([str(tmp_path), "--stability", "0.9"]) == 0
    out = capsys.readouterr().out
    assert "Hopper.run.perfect lsiq: not pooled, seed 1 is in several run dirs (" in out
    assert "lsiq, 2 seeds" not in out and "lsiq, 3 seeds" not in out
