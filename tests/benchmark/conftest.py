"""Fixtures shared by the benchmark tests."""
from __future__ import annotations

import json

import pytest
from benchmark_fixtures import finished_run, tiny_protocol, write_protocol


@pytest.fixture
def grid(tmp_path, monkeypatch):
    """The tiny protocol with: Hopper gail complete (3 seeds; seed 2 evaluated at 104/208 as an on-policy run
    fitting in batches would be), Hopper bc 2 of 3 seeds (seed 2 unfinished), UnitreeH1 gail 1 seed (no expert
    baseline: scored by return), a vail run of another budget, UnitreeH1.run.perfect blocked (no expert)."""
    monkeypatch.delenv("LOCO_IL_EXPERTS", raising=False)
    path = write_protocol(tmp_path, "tiny", tiny_protocol())
    logs = tmp_path / "logs"
    hop = logs / "Hopper.run.perfect"
    gail_details = [{"terminated": 3, "episodes": 10, "length_mean": 812.4, "wall_time": 1200.4},
                    {"terminated": 0, "episodes": 10, "length_mean": 1000.0, "wall_time": 1310.6},
                    {"terminated": 1, "episodes": 10, "length_mean": 955.5, "wall_time": 95.2}]
    for seed, (a, b, c) in enumerate([(0.2, 0.5, 0.8), (0.3, 0.6, 0.9), (0.4, 0.7, 1.0)]):
        steps = (104, 208) if seed == 2 else (100, 200)
        finished_run(hop / "gail" / f"seed{seed}", "Hopper.run.perfect", "gail", seed, 300, c, 1000.0 * c,
                     [(steps[0], a, 100 * a), (steps[1], b, 100 * b), (300, c, 100 * c)],
                     details=gail_details[seed], device="cuda" if seed == 2 else "cpu")
    for seed, score in ((0, 0.95), (1, 1.05)):     # bc seed 1 evaluated 8 episodes, seed 0 says nothing more
        finished_run(hop / "bc" / f"seed{seed}", "Hopper.run.perfect", "bc", seed, 50, score, 3000.0 + seed,
                     [(10, 0.5, 1.0), (50, score, 2.0)], unit="gradient steps",
                     details={"terminated": 2, "episodes": 8, "length_mean": 700.0} if seed else None)
    (hop / "bc" / "seed2").mkdir(parents=True)
    (hop / "bc" / "seed2" / "checkpoint.json").write_text(json.dumps({"step": 20}))
    finished_run(hop / "vail" / "seed0", "Hopper.run.perfect", "vail", 0, 5000, 0.5, 50.0, [(5000, 0.5, 50.0)])
    finished_run(logs / "UnitreeH1.walk.real" / "gail" / "seed0", "UnitreeH1.walk.real", "gail", 0, 300, None,
                 523.4, [(100, None, 40.0), (200, None, 60.0), (300, None, 523.4)])
    return path, logs, tmp_path / "out"
