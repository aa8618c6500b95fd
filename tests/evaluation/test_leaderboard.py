"""The leaderboard builder on fixture runs written here: exact Markdown and CSV, CIs, curves, published column."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from loco_il.evaluation import leaderboard

# Student-t quantiles t(0.975, dof), from tables (not from the code under test)
T975 = {1: 12.706204736174707, 2: 4.302652729911275}

RUNS = [  # (task, dataset, algorithm, seed, final return, normalized score)
    ("Hopper.run", "perfect", "lsiq", 0, 100.0, 0.5),
    ("Hopper.run", "perfect", "lsiq", 1, 110.0, 0.6),
    ("Hopper.run", "perfect", "lsiq", 2, 120.0, 0.7),
    ("Hopper.run", "perfect", "bc", 0, 50.0, 0.2),
    ("InvertedPendulum.balance", "perfect", "sqil", 0, 1000.0, None),
    ("InvertedPendulum.balance", "perfect", "sqil", 1, 900.0, None),
]


def make_runs(root: Path) -> None:
    for task, dataset, algo, seed, ret, norm in RUNS:
        d = root / f"{task}.{dataset}" / algo / f"seed{seed}"
        d.mkdir(parents=True)
        (d / "eval.json").write_text(json.dumps({
            "task_id": f"{task}.{dataset}", "task": task, "dataset_type": dataset, "algorithm": algo, "name": algo,
            "seed": seed, "steps": 1000, "return_mean": ret, "return_std": 1.0, "normalized_score": norm}))
        lines = ["step,env_steps,updates,episodes,wall_time,steps_per_s,train_return,eval_return_mean,"
                 "eval_return_std,eval_episodes,normalized_score"]
        lines += [f"{s},{s},{s},1,1.0,100.0,,{ret * s / 1000},0.0,5," for s in (500, 1000)]
        (d / "log.csv").write_text("\n".join(lines) + "\n")
    broken = root / "broken" / "seed0"
    broken.mkdir(parents=True)
    (broken / "eval.json").write_text("{not json")


def test_statistics_use_the_t_distribution():
    mean, half = leaderboard.mean_ci([100.0, 110.0, 120.0])
    assert mean == pytest.approx(110.0)
    assert half == pytest.approx(T975[2] * 10.0 / 3 ** 0.5)          # 24.84; a normal 1.96 would give 11.32
    assert leaderboard.mean_ci([5.0]) == (5.0, None)


def test_tables_exact(tmp_path):
    make_runs(tmp_path / "results")
    warnings = []
    res = leaderboard.build(tmp_path / "results", tmp_path / "out", warn=warnings.append)
    assert res["n_runs"] == 6 and len(warnings) == 1 and "broken" in warnings[0]

    lsiq_ci = T975[2] * 10.0 / 3 ** 0.5          # 24.8414
    sqil_ci = T975[1] * (50.0 * 2 ** 0.5) / 2 ** 0.5   # 635.3102
    assert f"{lsiq_ci:.2f}" == "24.84" and f"{sqil_ci:.2f}" == "635.31"
    expected_md = (
        "# loco_il leaderboard\n"
        "\n"
        "Mean ± 95 % confidence interval over seeds (Student-t, n-1 degrees of freedom; no interval for a single "
        "seed) of each run's final evaluation return. Normalized score: 0 = uniform random actions, 1 = the task's "
        "expert (loco_il/datasets/baselines.yaml); n/a where the task has no baseline.\n"
        "\n"
        "| task | dataset | algorithm | budget | seeds | return | normalized | published |\n"
        "|---|---|---|---|---|---|---|---|\n"
        "| Hopper.run | perfect | bc | 1000 steps | 1 | 50.00 | 0.200 | n/a |\n"
        "| Hopper.run | perfect | lsiq | 1000 steps | 3 | 110.00 ± 24.84 | 0.600 ± 0.248 | n/a |\n"
        "| InvertedPendulum.balance | perfect | sqil | 1000 steps | 2 | 950.00 ± 635.31 | n/a | n/a |\n"
        "\n"
        "published: scores from loco_il/evaluation/published.yaml. LocoMuJoCo publishes no baseline scores "
        "(loco-mujoco issue #13); \"n/a\" = no published number for that row.\n")
    assert (tmp_path / "out" / "leaderboard.md").read_text() == expected_md
    expected_csv = (
        "task,dataset,algorithm,budget,n_seeds,seeds,return_mean,return_ci95,normalized_mean,normalized_ci95,"
        "published,published_source\n"
        "Hopper.run,perfect,bc,1000 steps,1,0,50.0000,,0.2000,,,\n"
        "Hopper.run,perfect,lsiq,1000 steps,3,0 1 2,110.0000,24.8414,0.6000,0.2484,,\n"
        "InvertedPendulum.balance,perfect,sqil,1000 steps,2,0 1,950.0000,635.3102,,,,\n")
    assert (tmp_path / "out" / "leaderboard.csv").read_text() == expected_csv

    curves = sorted(p.name for p in (tmp_path / "out" / "curves").iterdir())
    assert curves == ["Hopper.run.perfect.png", "InvertedPendulum.balance.perfect.png"]
    assert all((tmp_path / "out" / "curves" / c).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for c in curves)


def test_published_column_and_cli(tmp_path, capsys):
    make_runs(tmp_path / "results")
    pub = tmp_path / "published.yaml"
    pub.write_text("entries:\n  - {task: Hopper.run, dataset: perfect, algorithm: LSIQ, value: '0.9 (normalized)', "
                   "source: 'a test fixture'}\n")
    assert leaderboard.main([str(tmp_path / "results"), "--published", str(pub), "--no-plots"]) == 0
    out = capsys.readouterr().out
    assert "| Hopper.run | perfect | lsiq | 1000 steps | 3 | 110.00 ± 24.84 | 0.600 ± 0.248 | 0.9 (normalized) |" in out
    assert "| Hopper.run | perfect | bc | 1000 steps | 1 | 50.00 | 0.200 | n/a |" in out
    assert "Hopper.run,perfect,lsiq,1000 steps,3,0 1 2,110.0000,24.8414,0.6000,0.2484,0.9 (normalized),a test fixture" in \
        (tmp_path / "results" / "leaderboard.csv").read_text()
    assert not (tmp_path / "results" / "curves").exists()
    # the shipped file loads (it is empty on purpose) and an empty folder is an error
    assert leaderboard.load_published() == []
    (tmp_path / "empty").mkdir()
    assert leaderboard.main([str(tmp_path / "empty")]) == 1
