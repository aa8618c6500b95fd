"""`run` end to end on a one-cell protocol with a minuscule budget: train.py's multirun makes the run, a second
`run` skips it as finished, `table` reports it. BC on Hopper (the shipped expert; 4 episodes of data, cached in a
private folder), 20 gradient steps."""
from __future__ import annotations

import csv
import json

import pytest
from benchmark_fixtures import write_protocol

from loco_il.benchmark import __main__ as cli

PROTOCOL = {
    "seeds": [0],
    "report_at": [],
    "eval": {"episodes": 1, "final_episodes": 1, "similarity": False},
    "overrides": {"logger": "csv", "dataset.n_episodes": 4, "hydra/job_logging": "disabled"},
    "families": {"offline": {"algos": ["bc"], "n_steps": 20, "eval_every": 10, "unit": "gradient"}},
    "parts": {"tiny": {"dataset": "perfect", "tasks": ["Hopper.run"], "algorithms": ["bc"]}},
}


@pytest.mark.slow
def test_run_skip_and_table(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path / "datasets"))
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    path = write_protocol(tmp_path, "one", PROTOCOL)
    logs = tmp_path / "logs"
    assert cli.main(["run", str(path), "--results-dir", str(logs)]) == 0
    run_dir = logs / "Hopper.run.perfect" / "bc" / "seed0"
    result = json.loads((run_dir / "eval.json").read_text())
    assert (result["steps"], result["step_unit"], result["name"]) == (20, "gradient steps", "bc")
    assert [int(float(r["step"])) for r in csv.DictReader(open(run_dir / "log.csv"))] == [10, 20]
    out = capsys.readouterr().out
    assert "1 not started; 1 to run" in out and "sweep 1/1, 1 run(s): python train.py -m task=Hopper.run.perfect" in out

    assert cli.main(["run", str(path), "--results-dir", str(logs)]) == 0
    assert capsys.readouterr().out.splitlines()[-2:] == [
        f"[benchmark] one: 1 cells, 1 runs in {logs}: 1 finished; 0 to run", "[benchmark] nothing to run"]

    assert cli.main(["table", str(path), "--results-dir", str(logs), "--out", str(tmp_path / "out")]) == 0
    md = (tmp_path / "out" / "one.md").read_text()
    assert "| Hopper.run.perfect | bc | 20 gradient steps | 1/1 | " in md and "None: every run" in md
    assert (tmp_path / "out" / "curves" / "one" / "Hopper.run.perfect.png").is_file()
