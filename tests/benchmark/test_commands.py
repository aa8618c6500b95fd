"""The train.py commands of a protocol: exactly the missing runs, grouped into as few Hydra sweeps as possible,
with the protocol's settings, printed by `run --dry-run`."""
from __future__ import annotations

from collections import Counter

from benchmark_fixtures import finished_run, tiny_protocol, write_protocol

from loco_il.benchmark import __main__ as cli
from loco_il.benchmark.cells import Selection, select
from loco_il.benchmark.commands import cell_command, fixed_overrides, hydra_value, plan
from loco_il.benchmark.protocol import load_protocol

COMMON = "eval.episodes=5 eval.final_episodes=10 logger=csv"


def _expanded(launches) -> Counter:
    """(task, algo, seed, fixed settings) of every run the sweeps make."""
    return Counter((t, a, s, lch.fixed) for lch in launches for t in lch.tasks for a in lch.algos for s in lch.seeds)


def test_plan_covers_exactly_the_missing_runs(tmp_path):
    proto = load_protocol(write_protocol(tmp_path, "tiny", tiny_protocol()))
    cells = select(proto, Selection(parts=("perfect",)))
    every = [(c, s) for c in cells for s in c.seeds]
    some = [(c, s) for c, s in every if not (c.label == "vail" and s == 1)]
    for runs in (every, some):
        wanted = Counter((c.task_id, c.algo, s, fixed_overrides(proto, c, tmp_path)) for c, s in runs)
        assert _expanded(plan(proto, runs, tmp_path)) == wanted
    # gail and vail share a sweep when they miss the same runs; lsiq and its variant differ in settings
    assert [lch.algos for lch in plan(proto, every, tmp_path)] == [("gail", "vail"), ("lsiq",), ("lsiq",), ("bc",)]
    assert [(lch.algos, lch.seeds) for lch in plan(proto, some, tmp_path)][:2] == [(("gail",), (0, 1, 2)),
                                                                                   (("vail",), (0, 2))]


def test_dry_run_prints_the_sweeps(tmp_path, capsys):
    path = write_protocol(tmp_path, "tiny", tiny_protocol())
    logs = tmp_path / "logs"
    finished_run(logs / "Hopper.run.perfect" / "bc" / "seed0", "Hopper.run.perfect", "bc", 0, 50, 1.0, 3000.0, [],
                 unit="gradient steps")
    code = cli.main(["run", str(path), "--dry-run", "--results-dir", str(logs), "--tasks", "Hopper.run",
                     "hydra/launcher=joblib", "hydra.launcher.n_jobs=2"])
    out = capsys.readouterr().out.splitlines()
    assert code == 0
    assert out[0] == (f"[benchmark] tiny: 5 cells, 15 runs in {logs}: 1 finished, 14 not started; 14 to run")
    launcher = "hydra/launcher=joblib hydra.launcher.n_jobs=2"
    assert out[1:] == [   # cheapest sweeps first (at these budgets, the evaluations dominate)
        f"python train.py -m task=Hopper.run.perfect algo=gail,vail seed=0,1,2 n_steps=300 eval.every=100 {COMMON} "
        f"results_dir={logs} {launcher}",
        f"python train.py -m task=Hopper.run.perfect algo=bc seed=1,2 n_steps=50 eval.every=10 {COMMON} "
        f"results_dir={logs} {launcher}",
        f"python train.py -m task=Hopper.run.perfect algo=lsiq seed=0,1,2 n_steps=200 eval.every=100 {COMMON} "
        f"results_dir={logs} {launcher}",
        f"python train.py -m task=Hopper.run.perfect algo=lsiq seed=0,1,2 n_steps=200 eval.every=100 {COMMON} "
        f"name=lsiq_twin algo.params.n_critics=2 results_dir={logs} {launcher}",
    ]


def test_dry_run_skips_blocked_cells_and_says_why(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("LOCO_IL_EXPERTS", raising=False)
    path = write_protocol(tmp_path, "tiny", tiny_protocol())
    assert cli.main(["run", str(path), "--dry-run", "--results-dir", str(tmp_path), "--tasks", "UnitreeH1.run.perfect"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].endswith("15 not started; 0 to run, 15 blocked")
    assert out[1].startswith("[benchmark] skipped UnitreeH1.run.perfect: no expert for UnitreeH1.run: train one")
    assert len(out) == 2


def test_cell_command_is_relative_to_the_checkout_and_names_the_variant():
    proto = load_protocol("small")
    cell = next(c for c in select(proto) if c.label == "lsiq_mixture_2critics_ln" and c.task_id == "Hopper.run.perfect")
    assert cell_command(proto, cell) == (
        "python train.py -m task=Hopper.run.perfect algo=lsiq seed=0,1,2 n_steps=200000 eval.every=10000 "
        "eval.episodes=5 eval.final_episodes=10 eval.seed=1000 logger=csv name=lsiq_mixture_2critics_ln "
        "algo.params.objective=mixture algo.params.n_critics=2 algo.params.critic_layer_norm=true "
        "results_dir=benchmarks/leaderboard/logs/small")


def test_hydra_values():
    assert [hydra_value(v) for v in (True, None, [256, 256], 3e-4, "mixture")] == [
        "true", "null", "[256,256]", "0.0003", "mixture"]


def test_overrides_that_change_results_are_pointed_out(tmp_path, capsys):
    path = write_protocol(tmp_path, "tiny", tiny_protocol())
    cli.main(["run", str(path), "--dry-run", "--results-dir", str(tmp_path), "--tasks", "UnitreeH1.walk",
              "device=cuda", "algo.params.max_kl=0.01"])
    out = capsys.readouterr().out
    assert "note: algo.params.max_kl=0.01 changes the runs' settings beyond the protocol" in out
    assert "device=cuda changes" not in out
