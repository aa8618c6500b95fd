"""The command line: one-line errors with their fix, and `prune` deleting only finished runs' checkpoints."""
from __future__ import annotations

import json

from benchmark_fixtures import finished_run, tiny_protocol, write_protocol

from loco_il.benchmark import __main__ as cli


def _error_line(capsys, argv) -> str:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err
    return err


def test_errors_are_one_line_with_the_fix(capsys, tmp_path):
    assert "unknown protocol 'nope'; known: paper, small" in _error_line(capsys, ["run", "nope"])
    assert "no algorithm 'ppo' in protocol small" in _error_line(capsys, ["run", "small", "--algos", "ppo"])
    assert "table takes no train.py overrides (device=cuda)" in _error_line(capsys, ["table", "small", "device=cuda"])
    bad = write_protocol(tmp_path, "bad", tiny_protocol(seeds="0"))
    assert "bad.yaml: seeds must be a non-empty list" in _error_line(capsys, ["cost", str(bad)])


def test_usage_without_a_command(capsys):
    assert cli.main([]) == 2
    assert "python -m loco_il.benchmark run small --dry-run" in capsys.readouterr().err
    assert cli.main(["--help"]) == 0


def test_prune_deletes_checkpoints_of_finished_runs_only(tmp_path, capsys):
    path = write_protocol(tmp_path, "tiny", tiny_protocol())
    logs = tmp_path / "logs"
    done = logs / "Hopper.run.perfect" / "gail" / "seed0"
    finished_run(done, "Hopper.run.perfect", "gail", 0, 300, 0.5, 10.0, [(300, 0.5, 10.0)])
    running = logs / "Hopper.run.perfect" / "gail" / "seed1"
    running.mkdir(parents=True)
    for d in (done, running):
        (d / "checkpoint.pt").write_bytes(b"x" * 2**20)
        (d / "checkpoint.json").write_text(json.dumps({"step": 100}))
        (d / "final_agent.pt").write_bytes(b"agent")
    assert cli.main(["prune", str(path), "--results-dir", str(logs), "--dry-run"]) == 0
    assert "would free 1 MiB of checkpoints in 1 finished run(s)" in capsys.readouterr().out
    assert (done / "checkpoint.pt").is_file()
    assert cli.main(["prune", str(path), "--results-dir", str(logs)]) == 0
    assert sorted(p.name for p in done.iterdir()) == ["eval.json", "final_agent.pt", "log.csv"]
    assert sorted(p.name for p in running.iterdir()) == ["checkpoint.json", "checkpoint.pt", "final_agent.pt"]
