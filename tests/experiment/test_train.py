"""End-to-end tests of `train.py` (Hydra app), resume, sweeps and `python -m loco_il.evaluation`.

Every run is a subprocess on InvertedPendulum.balance.perfect with a tiny budget and a stand-in expert
(tests/train_helpers.py).
"""
from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import mujoco
import pytest
import torch
from train_helpers import (FAST, ROOT, TASK, csv_rows, make_env_vars, run_dir, train,  # tests/ is on sys.path
                           train_command)

pytestmark = pytest.mark.slow      # subprocess runs of train.py: the full suite (CI) runs them; -m "not slow" skips them

#: a tiny GAIL: small networks, short on-policy batches
TINY_GAIL = ["algo=gail", "algo.core.n_steps_per_fit=200", "algo.policy.hidden=[32,32]",
             "algo.params.disc_hidden=[32]", "algo.params.vf_hidden=[32]", "algo.params.disc_batch_size=200",
             "algo.params.vf_batch_size=100", "algo.params.train_disc_every=1", "algo.params.cg_iters=10"]


@pytest.fixture(scope="module")
def env_vars(tmp_path_factory) -> dict:
    return make_env_vars(tmp_path_factory.mktemp("experiment"))


def test_end_to_end_train_evaluate_and_rerun(env_vars, tmp_path):
    """The default task with BC and a tiny budget: every run file, a learned policy, the printed
    table; `python -m loco_il.evaluation` scores it; re-running the finished command does not train again."""
    results = tmp_path / "results"
    proc = train(env_vars, results, "algo=bc", "n_steps=300", "eval.every=100")
    d = run_dir(results)
    for name in ("config.yaml", "log.csv", "log.jsonl", "checkpoint.pt", "final_agent.pt", "eval.json"):
        assert (d / name).is_file(), f"missing {name}; run dir holds {sorted(p.name for p in d.iterdir())}"
    assert "Final evaluation" in proc.stdout and "| InvertedPendulum.balance | perfect | bc | 0 | 300 |" in proc.stdout

    rows = csv_rows(d / "log.csv")
    assert [int(r["step"]) for r in rows] == [100, 200, 300]
    assert all(r["eval_return_mean"] not in ("", None) for r in rows)
    jrows = [json.loads(line) for line in (d / "log.jsonl").read_text().splitlines()]
    assert [r["step"] for r in jrows] == [100, 200, 300] and "fit/bc_loss" in jrows[-1]

    ev = json.loads((d / "eval.json").read_text())
    assert (ev["task_id"], ev["algorithm"], ev["dataset_type"], ev["steps"], ev["episodes"]) == (TASK, "bc", "perfect", 300, 3)
    # the stand-in expert balances for all 1000 steps; random actions last ~5, an untrained policy ~25
    assert max(ev["returns"]) == 1000, ev["returns"]
    # episodes that fell (terminal state before the horizon) are counted, in eval.json and every log row
    assert ev["terminated"] == sum(n < 1000 for n in ev["lengths"])
    assert all(0 <= r["eval_terminated"] <= r["eval_episodes"] for r in jrows)
    assert all(r["eval_terminated"] not in ("", None) for r in rows)
    assert ev["similarity"]["reference"] == "test split" and ev["similarity"]["nn_distance"] >= 0
    assert ev["critic_diverged_at"] is None          # BC has no critic to diverge
    # the machine it finished on: CPU and cores, the torch device, the library versions (no host name)
    machine = ev["finished_on"]
    assert machine["device"] == "cpu" and "gpu" not in machine and machine["cpu_cores"] >= 1
    assert machine["versions"]["torch"] == torch.__version__ and machine["versions"]["mujoco"] == mujoco.__version__
    # the default baselines have no expert return for this task: no score, and a message saying why
    if ev["normalized_score"] is None:
        assert "python -m loco_il.datasets.baselines update" in ev["normalized_score_note"]

    cfg = (d / "config.yaml").read_text()
    assert f"task_id: {TASK}" in cfg and "${" not in cfg            # resolved
    assert "lr: 0.0003" in cfg                                        # the task file's per-algorithm tuning

    score = subprocess.run([sys.executable, "-m", "loco_il.evaluation", f"run_dir={d}", "episodes=2",
                            f"out={tmp_path / 'score.json'}"], cwd=ROOT, env=env_vars, capture_output=True,
                           text=True, timeout=120)
    assert score.returncode == 0, score.stderr[-2000:]
    res = json.loads(score.stdout.strip().splitlines()[-1])
    assert res["episodes"] == 2 and len(res["returns"]) == 2 and res["agent_file"].endswith("final_agent.pt")
    assert json.loads((tmp_path / "score.json").read_text())["return_mean"] == res["return_mean"]
    assert "| InvertedPendulum.balance | perfect | bc |" in score.stdout

    mtime = (d / "final_agent.pt").stat().st_mtime_ns
    again = train(env_vars, results, "algo=bc", "n_steps=300", "eval.every=100")
    assert "already finished" in again.stdout
    assert (d / "final_agent.pt").stat().st_mtime_ns == mtime
    # the same run dir with another configuration is refused, naming the difference and the way out
    other = train(env_vars, results, "algo=bc", "n_steps=300", "eval.every=100", "algo.params.lr=0.01", check=False)
    assert other.returncode == 2, other.stderr[-2000:]
    assert "algo.params.lr: 0.0003 -> 0.01" in other.stderr and "resume=false" in other.stderr
    assert (d / "final_agent.pt").stat().st_mtime_ns == mtime


def test_stopped_run_resumes_to_the_same_result(env_vars, tmp_path):
    """GAIL stopped after 600 of 1000 env steps (checkpoints every 400: 200 steps are lost and redone)
    resumes and ends exactly like an uninterrupted run: same total steps, same log, same final returns."""
    common = [*TINY_GAIL, "n_steps=1000", "eval.every=200", "checkpoint_every=400"]
    stopped = tmp_path / "stopped"
    proc = train(env_vars, stopped, *common, "stop_after_steps=600", check=False)
    assert proc.returncode == 3, proc.stderr[-2000:]
    d = run_dir(stopped, "gail")
    assert not (d / "eval.json").exists()
    ckpt = torch.load(d / "checkpoint.pt", map_location="cpu", weights_only=False)
    assert ckpt["counters"]["step"] == 400 and ckpt["agent"]["attrs"]["n_fits"] == 2
    assert [int(r["step"]) for r in csv_rows(d / "log.csv")] == [200, 400, 600]   # 600 is redone on resume

    resumed = train(env_vars, stopped, *common)          # the same command, without the debug stop
    assert "resuming" in resumed.stdout + resumed.stderr
    full = tmp_path / "full"
    train(env_vars, full, *common)

    a, b = json.loads((d / "eval.json").read_text()), json.loads((run_dir(full, "gail") / "eval.json").read_text())
    assert a["steps"] == b["steps"] == 1000 and a["env_steps"] == b["env_steps"] == 1000
    assert a["returns"] == b["returns"]
    ra, rb = csv_rows(d / "log.csv"), csv_rows(run_dir(full, "gail") / "log.csv")
    assert [int(r["step"]) for r in ra] == [int(r["step"]) for r in rb] == [200, 400, 600, 800, 1000]
    assert [r["eval_return_mean"] for r in ra] == [r["eval_return_mean"] for r in rb]
    assert [r["train_return"] for r in ra] == [r["train_return"] for r in rb]
    assert torch.load(d / "checkpoint.pt", weights_only=False)["finished"]


#: a tiny LS-IQ (off-policy: its checkpoint holds a replay memory)
TINY_LSIQ = ["algo=lsiq", "algo.policy.hidden=[32,32]", "algo.params.critic_hidden=[32,32]",
             "algo.params.initial_replay_size=100", "algo.params.batch_size=32", "algo.params.expert_batch_size=32"]


def test_fork_branches_a_run_at_its_checkpoint(env_vars, tmp_path):
    """fork_from: a new run starts from another run's checkpoint (state, replay, log rows) with changed settings,
    trains on to its own budget and resumes as itself; the source run is left as it was."""
    results = tmp_path / "r"
    proc = train(env_vars, results, *TINY_LSIQ, "n_steps=600", "eval.every=200", "stop_after_steps=400", check=False)
    assert proc.returncode == 3, proc.stderr[-2000:]
    src = run_dir(results, "lsiq")
    src_rows = csv_rows(src / "log.csv")
    src_ckpt = torch.load(src / "checkpoint.pt", map_location="cpu", weights_only=False)
    assert src_ckpt["counters"]["step"] == 400

    fork = train(env_vars, results, *TINY_LSIQ, "n_steps=600", "eval.every=200", "name=lsiq_fork",
                 f"fork_from={src}", "algo.params.learn_alpha=true")
    out = fork.stdout + fork.stderr
    assert "forking" in out and "algo.params.learn_alpha: False -> True" in out
    d = run_dir(results, "lsiq_fork")
    rows = csv_rows(d / "log.csv")
    assert [int(r["step"]) for r in rows] == [200, 400, 600]
    assert rows[:2] == src_rows[:2]                       # the curve up to the fork point is the source's
    ckpt = torch.load(d / "checkpoint.pt", map_location="cpu", weights_only=False)
    assert ckpt["finished"] and ckpt["counters"]["step"] == 600
    assert ckpt["agent"]["attrs"]["n_transitions"] == 600  # 400 restored + 200 trained after the fork
    assert ckpt["config"]["algo"]["params"]["learn_alpha"] is True
    assert torch.load(src / "checkpoint.pt", map_location="cpu", weights_only=False)["counters"]["step"] == 400

    again = train(env_vars, results, *TINY_LSIQ, "n_steps=600", "eval.every=200", "name=lsiq_fork",
                  f"fork_from={src}", "algo.params.learn_alpha=true")
    assert "already finished" in again.stdout and "forking" not in again.stdout + again.stderr

    wrong = train(env_vars, results, "algo=bc", "n_steps=600", "name=bc_fork", f"fork_from={src}", check=False)
    assert wrong.returncode == 2 and "algo.name='lsiq'" in wrong.stderr, wrong.stderr[-2000:]

    shapes = train(env_vars, results, *TINY_LSIQ, "n_steps=600", "eval.every=200", "name=lsiq_fork1",
                   f"fork_from={src}", "algo.params.n_critics=2", check=False)
    assert shapes.returncode == 2 and "does not fit this config's networks" in shapes.stderr, shapes.stderr[-2000:]

    # a kept checkpoint file of a run can be loaded and evaluated in place of the run's latest one
    from loco_il.evaluation import load_run_agent
    agent, source = load_run_agent(src, checkpoint=d / "checkpoint.pt")
    assert "step 600" in source
    latest, latest_source = load_run_agent(src)
    assert "step 400" in latest_source
    differs = any(not torch.equal(a, b) for a, b in zip(agent.policy_module.state_dict().values(),
                                                       latest.policy_module.state_dict().values()))
    assert differs                                         # 200 more updates moved the policy
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_run_agent(src, checkpoint=d / "missing.pt")
    modes = subprocess.run([sys.executable, "benchmarks/eval_modes.py", str(src), "--episodes", "1", "--checkpoints",
                            str(d / "checkpoint.pt"), str(src / "checkpoint.pt")], cwd=ROOT, env=env_vars,
                           capture_output=True, text=True, timeout=120, check=True).stdout
    rows = [line for line in modes.splitlines() if "(step " in line]
    assert len(rows) == 2 and "step 600" in rows[0] and "step 400" in rows[1], modes
    cells = r"\s+(-?\d+\.\d\d)\s+(\d+)\s+([01])/1"                       # score, mean length, falls of 1 episode
    for line in rows:
        m = re.search(cells * 2 + r"\s*$", line)
        assert m, modes                                    # one set for the mean action, one for sampled actions
        assert all(1 <= int(m.group(i)) <= 1000 for i in (2, 5)), modes


def test_checkpoints_kept_above_a_score_and_forked_from(env_vars, tmp_path):
    """keep_checkpoints_above: every evaluation scoring at least the threshold also keeps that step's checkpoint
    as kept/step<N>.pt, also between checkpoint_every points; fork_from takes such a file, with the source
    run's curve up to that step."""
    results = tmp_path / "r"
    train(env_vars, results, *TINY_LSIQ, "n_steps=600", "eval.every=200", "checkpoint_every=600",
          "keep_checkpoints_above=-1e9")
    d = run_dir(results, "lsiq")
    kept = sorted((d / "kept").glob("*.pt"), key=lambda p: int(p.stem[4:]))
    assert [p.name for p in kept] == ["step200.pt", "step400.pt", "step600.pt"]
    # each with its checksum file, which a fork from it verifies
    assert sorted(p.name for p in (d / "kept").iterdir()) == sorted([p.name for p in kept] +
                                                                     [p.name + ".sha256" for p in kept])
    steps = [torch.load(p, map_location="cpu", weights_only=False)["counters"]["step"] for p in kept]
    assert steps == [200, 400, 600]
    scores = [float(r["normalized_score"]) for r in csv_rows(d / "log.csv")]

    # the same run with the step-400 score as threshold keeps exactly the evaluations at or above it
    proc = train(env_vars, results, *TINY_LSIQ, "n_steps=600", "eval.every=200", "checkpoint_every=600",
                 "name=lsiq_sel", f"keep_checkpoints_above={scores[1]!r}")
    d_sel = run_dir(results, "lsiq_sel")
    assert [float(r["normalized_score"]) for r in csv_rows(d_sel / "log.csv")] == scores   # same seed, same run
    expected = sorted(f"step{200 * (i + 1)}.pt" for i, s in enumerate(scores) if s >= scores[1])
    assert sorted(p.name for p in (d_sel / "kept").glob("*.pt")) == expected
    assert proc.stdout.count("checkpoint kept as") == len(expected)

    fork = train(env_vars, results, *TINY_LSIQ, "n_steps=400", "eval.every=200", "name=lsiq_fork200",
                 f"fork_from={kept[0]}", "algo.params.actor_lr=1e-4")
    assert "forking" in fork.stdout + fork.stderr
    rows = csv_rows(run_dir(results, "lsiq_fork200") / "log.csv")
    assert [int(r["step"]) for r in rows] == [200, 400]
    assert float(rows[0]["normalized_score"]) == scores[0]   # the source's row at the fork point

    bad = train(env_vars, results, *TINY_LSIQ, "n_steps=200", "name=lsiq_bad", "keep_checkpoints_above=high",
                check=False)
    assert bad.returncode == 2 and "keep_checkpoints_above='high'" in bad.stderr, bad.stderr[-2000:]


def test_discount_and_actor_average_from_the_command_line(env_vars, tmp_path):
    """algo.params.gamma replaces the task's discount; algo.params.actor_ema adds an evaluation of the actor's
    moving average at every evaluation point and in eval.json."""
    results = tmp_path / "r"
    proc = train(env_vars, results, *TINY_LSIQ, "n_steps=400", "eval.every=200", "name=lsiq_ema",
                 "algo.params.gamma=0.98", "algo.params.actor_ema=0.01")
    d = run_dir(results, "lsiq_ema")
    rows = [json.loads(line) for line in (d / "log.jsonl").read_text().splitlines()]
    assert [r["step"] for r in rows] == [200, 400]
    assert all(r["eval_ema_return_mean"] > 0 and 0 < r["eval_ema_length_mean"] <= 1000 for r in rows)
    assert [r.get("normalized_score_ema") is not None for r in csv_rows(d / "log.csv")] == [True, True]
    result = json.loads((d / "eval.json").read_text())
    assert result["ema_actor"]["return_mean"] > 0 and "normalized_score" in result["ema_actor"]
    assert proc.stdout.count("actor average") >= 2, proc.stdout[-2000:]
    from loco_il.evaluation import load_run_agent
    agent, _ = load_run_agent(d)
    assert agent.gamma == 0.98 and agent.actor_ema == 0.01 and agent.policy_ema is not None
    plain = train(env_vars, results, *TINY_LSIQ, "n_steps=200", "eval.every=200", "name=lsiq_plain")
    assert "actor average" not in plain.stdout
    assert "ema_actor" not in json.loads((run_dir(results, "lsiq_plain") / "eval.json").read_text())


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_cuda_run_checkpoints_and_resumes_on_the_cpu(env_vars, tmp_path):
    """device=cuda trains LS-IQ on the GPU (updates replayed from a CUDA graph); its checkpoint (with the replay
    memory) resumes with device=cpu and the run finishes there, as a GPU job moved to a CPU machine would."""
    results = tmp_path / "r"
    common = [*TINY_LSIQ, "n_steps=400", "eval.every=100", "checkpoint_every=200"]
    proc = train(env_vars, results, *common, "device=cuda", "algo.params.cuda_graph=true", "stop_after_steps=300",
                 check=False)
    assert proc.returncode == 3, proc.stderr[-2000:]
    d = run_dir(results, "lsiq")
    ckpt = torch.load(d / "checkpoint.pt", map_location="cpu", weights_only=False)
    assert ckpt["counters"]["step"] == 200 and "cuda" in ckpt["agent"]["rng"]
    resumed = train(env_vars, results, *common, "device=cpu", "algo.params.cuda_graph=false")
    assert "resuming" in resumed.stdout + resumed.stderr
    result = json.loads((d / "eval.json").read_text())
    assert result["steps"] == 400 and result["return_mean"] > 0
    from loco_il.evaluation import load_run_agent
    agent, _ = load_run_agent(d)
    assert agent.device.type == "cpu" and agent.n_updates > 0


def test_a_run_resumes_with_another_device_or_cuda_graph_but_not_another_objective():
    from loco_il.experiment.checkpoint import config_differences
    ran = {"device": "cuda", "algo": {"name": "lsiq", "params": {"cuda_graph": True, "n_critics": 2}}}
    on_cpu = {"device": "cpu", "algo": {"name": "lsiq", "params": {"cuda_graph": False, "n_critics": 2}}}
    assert config_differences(ran, on_cpu) == []
    on_cpu["algo"]["params"]["n_critics"] = 1
    assert config_differences(ran, on_cpu) == ["algo.params.n_critics: 2 -> 1"]
    # a key added since the run was checkpointed: resumes with the value that behaves as the run did
    on_cpu["algo"]["params"].update(n_critics=2, critic_layer_norm=False)
    assert config_differences(ran, on_cpu) == []
    on_cpu["algo"]["params"]["critic_layer_norm"] = True
    assert config_differences(ran, on_cpu) == ["algo.params.critic_layer_norm: False -> True"]
    # dataset.workers (added later) changes how the dataset is generated, not what it holds
    on_cpu["algo"]["params"]["critic_layer_norm"] = False
    assert config_differences({**ran, "dataset": {"n_episodes": 12}},
                              {**on_cpu, "dataset": {"n_episodes": 12, "workers": 8}}) == []


def test_killed_run_resumes(env_vars, tmp_path):
    """SIGKILL once the first checkpoint exists; the same command finishes the run with the full budget."""
    results = tmp_path / "results"
    args = ["algo=bc", "n_steps=2000", "eval.every=500", "checkpoint_every=100"]
    cmd = [sys.executable, "train.py", f"results_dir={results}", *FAST, *args]
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env_vars, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ckpt = run_dir(results) / "checkpoint.pt"
    try:
        deadline = time.time() + 240
        while not ckpt.exists() and proc.poll() is None and time.time() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, "the run ended before it could be killed"
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert not (run_dir(results) / "eval.json").exists()
    at = torch.load(ckpt, weights_only=False)["counters"]["step"]
    assert 0 < at < 2000
    out = train(env_vars, results, *args)
    assert f"resuming {run_dir(results)} at step {at}/2000" in out.stdout
    ev = json.loads((run_dir(results) / "eval.json").read_text())
    assert ev["steps"] == 2000
    steps = [int(r["step"]) for r in csv_rows(run_dir(results) / "log.csv")]
    assert steps == [500, 1000, 1500, 2000]


def start_and_signal(env_vars, results: Path, args: list[str], ready, delay: float = 0.0, multirun: bool = False):
    """Start train.py, send SIGTERM once `ready()` holds (plus `delay` seconds); returns (exit status, stderr,
    seconds from the signal to the exit)."""
    cmd = train_command(results, *args, multirun=multirun)
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env_vars, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 240
        while not ready() and proc.poll() is None and time.time() < deadline:
            time.sleep(0.05)
        time.sleep(delay)
        assert proc.poll() is None, "the run ended before it could be stopped"
        t0 = time.time()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=240)
        return proc.returncode, err, time.time() - t0
    finally:
        if proc.poll() is None:
            proc.kill()


def test_sigterm_stops_with_a_checkpoint_and_resumes(env_vars, tmp_path):
    """SIGTERM after the first evaluation of a BC run: it stops within 100 gradient steps with a checkpoint at
    that step (not only at an evaluation or checkpoint_every multiple), exit status 130; the same command
    finishes it."""
    results = tmp_path / "results"
    args = ["algo=bc", "n_steps=20000", "eval.every=500", "checkpoint_every=10000"]
    log = run_dir(results) / "log.csv"
    code, err, _ = start_and_signal(env_vars, results, args, lambda: log.exists() and csv_rows(log))
    assert code == 130, err[-2000:]
    at = torch.load(run_dir(results) / "checkpoint.pt", weights_only=False)["counters"]["step"]
    assert 0 < at < 20000 and at % 100 == 0
    assert f"stopped by SIGTERM at step {at}/20000, checkpoint saved" in err
    # every evaluation up to the stop is logged, none after it
    assert [int(r["step"]) for r in csv_rows(log)] == list(range(500, at + 1, 500))
    assert not (run_dir(results) / "eval.json").exists()
    # the small summary beside the checkpoint names its step, and the progress table shows where it resumes
    from loco_il.evaluation.progress import run_progress
    assert run_progress(run_dir(results))["resume_step"] == at
    resumed = train(env_vars, results, *args)
    assert f"resuming {run_dir(results)} at step {at}/20000" in resumed.stdout
    assert json.loads((run_dir(results) / "eval.json").read_text())["steps"] == 20000
    summary = json.loads((run_dir(results) / "checkpoint.json").read_text())
    assert (summary["step"], summary["finished"]) == (20000, True)
    assert run_progress(run_dir(results))["resume_step"] is None   # finished: nothing to resume


def test_sigterm_stops_an_online_run_at_its_next_fit(env_vars, tmp_path):
    """An online learner stops at the fit after the signal, not at the end of its 100k-step chunk: the
    checkpoint holds a whole number of fits (200 env steps each) and the run resumes from it. The signal is
    sent as soon as config.yaml exists, mostly while the envs, dataset and agent are still being built: the
    handler is already in place then (it once was not, and a loaded machine killed the run with no message)."""
    results = tmp_path / "results"
    args = [*TINY_GAIL, "n_steps=200000", "eval.every=100000", "checkpoint_every=100000"]
    config = run_dir(results, "gail") / "config.yaml"
    code, err, seconds = start_and_signal(env_vars, results, args, config.exists)
    assert code == 130, err[-2000:]
    ckpt = torch.load(run_dir(results, "gail") / "checkpoint.pt", weights_only=False)
    at, env_steps = ckpt["counters"]["step"], ckpt["counters"]["env_steps"]
    assert 0 <= at < 100000 and at % 200 == 0 and env_steps == at
    assert f"stopped by SIGTERM at step {at}/200000, checkpoint saved" in err
    assert seconds < 60, f"the stop took {seconds:.0f} s"
    resumed = train(env_vars, results, *args[:-3], f"n_steps={at + 400}", "eval.every=100000")
    assert f"resuming {run_dir(results, 'gail')} at step {at}/{at + 400}" in resumed.stdout
    assert json.loads((run_dir(results, "gail") / "eval.json").read_text())["steps"] == at + 400


def test_sigterm_during_the_setup_of_an_offline_run(env_vars, tmp_path):
    """BC signalled as soon as config.yaml exists: exit 130 with a checkpoint at a whole number of 100-step
    chunks, and only the evaluations it reached are logged (a stop before the first step logs no row at
    step 0)."""
    results = tmp_path / "results"
    args = ["algo=bc", "n_steps=20000", "eval.every=500", "checkpoint_every=10000"]
    code, err, _ = start_and_signal(env_vars, results, args, (run_dir(results) / "config.yaml").exists)
    assert code == 130, err[-2000:]
    at = torch.load(run_dir(results) / "checkpoint.pt", weights_only=False)["counters"]["step"]
    assert 0 <= at < 20000 and at % 100 == 0
    assert f"stopped by SIGTERM at step {at}/20000, checkpoint saved" in err
    log = run_dir(results) / "log.csv"
    assert [int(r["step"]) for r in (csv_rows(log) if log.exists() else [])] == list(range(500, at + 1, 500))


def test_resume_false_clears_the_run_dir(tmp_path):
    from loco_il.experiment.runner import Runner
    for name in ("checkpoint.pt", "checkpoint.json", "log.csv", "log.jsonl", "eval.json", "final_agent.pt"):
        (tmp_path / name).write_text("old")
    cfg = {"task_id": TASK, "algo": {"name": "bc"}, "resume": False}
    assert Runner(cfg, tmp_path)._prepare_dir() is None
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    with pytest.raises(Exception, match="nothing to resume"):
        Runner({**cfg, "resume": True}, tmp_path)._prepare_dir()


def test_wrong_algorithm_dataset_pair_fails_at_start(env_vars, tmp_path):
    proc = train(env_vars, tmp_path / "r", "task=UnitreeH1.walk.real", "algo=bc", check=False, timeout=120)
    assert proc.returncode == 2
    assert "BC cannot learn from a 'real' dataset" in proc.stderr
    assert not (tmp_path / "r" / "UnitreeH1.walk.real" / "bc" / "seed0" / "checkpoint.pt").exists()


def test_hydra_help_and_cfg(env_vars, tmp_path):
    out = subprocess.run([sys.executable, "train.py", "task=Hopper.run.perfect", "algo=gail", "seed=3", "--cfg", "job",
                          "--resolve"], cwd=ROOT, env=env_vars, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "task_id: Hopper.run.perfect" in out.stdout and "name: gail" in out.stdout and "seed: 3" in out.stdout
    hlp = subprocess.run([sys.executable, "train.py", "--help"], cwd=ROOT, env=env_vars, capture_output=True,
                         text=True, timeout=120)
    assert hlp.returncode == 0 and "python train.py -m algo=bc,sqil" in hlp.stdout and "algo: " in hlp.stdout


@pytest.mark.parametrize("launcher", ["joblib", "submitit_local"])
def test_multirun_launchers(env_vars, tmp_path, launcher):
    results = tmp_path / "results"
    extra = ["hydra.launcher.n_jobs=2"] if launcher == "joblib" else ["hydra.launcher.timeout_min=10"]
    train(env_vars, results, f"hydra/launcher={launcher}", *extra, "algo=bc", "seed=0,1", "n_steps=10", "eval.every=10",
          "eval.final_episodes=1", "eval.similarity=false", multirun=True)
    for seed in (0, 1):
        ev = json.loads((run_dir(results, seed=seed) / "eval.json").read_text())
        assert ev["seed"] == seed and ev["steps"] == 10


@pytest.mark.parametrize("algo", ["gail", "gaifo", "lsiqfo"])
def test_state_only_learners_train_on_a_real_dataset(env_vars, tmp_path, algo):
    """#4's `real` data (the quadruped's trot states, no actions) through train.py: the state-only learners
    run end to end and are scored against the task's baselines (tiny budgets: a smoke test, not learning)."""
    real = ["task=UnitreeA1.simple.real", "dataset.n_episodes=3", "+dataset.provider_kwargs={episode_steps:200}"]
    if algo == "lsiqfo":
        agent = ["algo=lsiq", "algo.name=lsiqfo", "n_steps=400", "algo.policy.hidden=[32,32]",
                 "algo.params.critic_hidden=[32,32]", "algo.params.initial_replay_size=200",
                 "algo.params.batch_size=64", "algo.params.expert_batch_size=64"]
    else:
        agent = [a.replace("algo=gail", f"algo={algo}") for a in TINY_GAIL] + ["n_steps=400"]
    train(env_vars, tmp_path / "r", *real, *agent, timeout=300)
    result = json.loads((tmp_path / "r" / "UnitreeA1.simple.real" / algo / "seed0" / "eval.json").read_text())
    assert result["dataset_type"] == "real" and result["env_steps"] == 400
    assert result["baseline"]["random"] is not None and result["normalized_score"] == pytest.approx(
        (result["return_mean"] - result["baseline"]["random"]) / (result["baseline"]["expert"] - result["baseline"]["random"]))


def test_sigterm_stops_the_whole_sweep(env_vars, tmp_path):
    """SIGTERM during the first job of a `-m` sweep: that job stops with its checkpoint and the later jobs do not
    start (the sweep's summary names them), exit status 1 (a job did not finish)."""
    results = tmp_path / "results"
    args = ["algo=bc", "seed=0,1", "n_steps=20000", "eval.every=500", "checkpoint_every=10000"]
    log = run_dir(results, seed=0) / "log.csv"
    code, err, _ = start_and_signal(env_vars, results, args, lambda: log.exists() and csv_rows(log), multirun=True)
    assert code == 1, err[-2000:]
    assert "stopped by SIGTERM at step" in err and (run_dir(results, seed=0) / "checkpoint.pt").exists()
    assert "not started: an earlier job of this sweep was stopped by SIGTERM" in err
    assert not (run_dir(results, seed=1) / "checkpoint.pt").exists()
