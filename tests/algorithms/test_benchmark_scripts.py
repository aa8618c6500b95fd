"""The benchmark scripts the RESULTS.md figures come from: they run, and their measures mean what they say."""
from __future__ import annotations

import re
import shutil
import subprocess
import sys

import pytest
import torch
from script_loader import BENCHMARKS, load_script


@pytest.mark.parametrize("name", sorted(p.stem for p in BENCHMARKS.glob("*.py")))
def test_every_benchmark_script_imports(name):
    """A renamed or removed library name breaks a script only when it runs; importing it finds that early."""
    assert callable(getattr(load_script(name), "main", None))


def quadratic_critic(obs: torch.Tensor, act: torch.Tensor) -> torch.Tensor:
    """Two heads, (2, N): Q(s, a) = -|a - target(s)|^2 with target(s) = 0.5 * obs[:, :2]; the second head lower."""
    q = -(act - 0.5 * obs[:, :2]).pow(2).sum(-1)
    return torch.stack([q, q - 1.0])


def test_q_gap_is_zero_or_less_at_the_critics_maximum_and_positive_away_from_it():
    q_gap = load_script("offpolicy_diagnostics").q_gap
    obs = torch.tensor([[0.4, -0.6, 3.0], [-1.0, 1.0, 0.0]])
    best = 0.5 * obs[:, :2]
    gap_at_best = q_gap(quadratic_critic, obs, best, n_actions=256)
    assert (gap_at_best <= 0).all()
    assert (gap_at_best > -0.05).all()   # 256 uniform actions in [-1, 1]^2 come close to the maximum
    worst = -torch.sign(best)            # the far corner: Q = -(1 + |target|)^2 summed
    gap_at_worst = q_gap(quadratic_critic, obs, worst, n_actions=256, chunk=1)
    assert torch.allclose(gap_at_worst, (1 + best.abs()).pow(2).sum(-1), atol=0.05)


@pytest.mark.slow
def test_il_speed_runs_and_compares_each_agent_with_the_bare_update_of_its_critic():
    out = subprocess.run([sys.executable, str(BENCHMARKS / "il_speed.py"), "--updates", "1", "--reps", "1",
                          "--offpolicy", "lsiq", "lsiqfo", "sqil", "--critic-layer-norm", "--unshared-forward",
                          "--onpolicy", "gail",
                          "--onpolicy-fits", "1", "--onpolicy-reps", "1", "--random-expert"],
                         capture_output=True, text=True, timeout=300, check=True).stdout
    offpolicy, onpolicy = out.split("## Off-policy")[1].split("## On-policy")
    off_rows = {m[0]: (float(m[1]), m[2]) for m in
                re.findall(r"^(\S+(?: SAC(?: \dQ)?(?:\+IDM)?)?(?: LN)?(?: unshared)?)\s+[\d.]+\s+([\d.]+)\s+"
                           r"(bare SAC(?: \dQ)?(?:\+IDM)?(?: LN)?)$", offpolicy, re.M)}
    assert {"bare SAC", "lsiq", "lsiqfo", "sqil", "lsiq LN", "lsiqfo LN", "sqil LN"} <= set(off_rows), out
    # LSIQ-fO's inverse dynamics model is one network more: its baseline trains one too, and the ratio
    # against SAC's networks alone is printed as well
    assert off_rows["lsiqfo"][1] == "bare SAC 1Q+IDM" and off_rows["lsiq"][1] == "bare SAC 1Q", out
    assert re.search(r"^lsiqfo against bare SAC 1Q \(.*\): [\d.]+$", offpolicy, re.M), out
    # --critic-layer-norm: each LayerNorm agent against the bare update with the same LayerNorm critic,
    # the bare LayerNorm update against the plain one, and what LayerNorm costs each agent
    assert off_rows["lsiq LN"][1] == "bare SAC 1Q LN" and off_rows["sqil LN"][1] == "bare SAC LN", out
    assert off_rows["lsiqfo LN"][1] == "bare SAC 1Q+IDM LN" and off_rows["bare SAC LN"][1] == "bare SAC", out
    for name in ("lsiq", "lsiqfo", "sqil"):
        assert re.search(rf"^{name}: LayerNorm / plain critic update time [\d.]+x$", offpolicy, re.M), out
        # --unshared-forward: the agent as before the policy forward was shared, against the same bare update
        assert off_rows[f"{name} unshared"][1] == off_rows[name][1], out
        assert re.search(rf"^{name}: unshared / shared policy forward, update time [\d.]+x$", offpolicy, re.M), out
    for name, (ratio, against) in off_rows.items():
        assert against in off_rows, out            # the bare update it is compared with was timed too
        if name == against:
            assert ratio == 1.0
    on_rows = dict(re.findall(r"^(\S+(?: env)?)\s+\d+\s+([\d.]+)$", onpolicy, re.M))
    assert float(on_rows["bare env"]) == 1.0 and 0 < float(on_rows["gail"]), out
    # the breakdown: with all the work split perfectly over two cores the ratio would at most double
    _, _, bound_free_fit, bound_two_cores = re.search(
        r"^gail\s+(\d+)\s+(\d+)\s+([\d.]+)\s+([\d.]+)$", onpolicy, re.M).groups()
    assert float(bound_two_cores) == pytest.approx(min(1.0, 2 * float(on_rows["gail"])), abs=0.011), out
    assert float(on_rows["gail"]) <= float(bound_free_fit) <= 1.0, out


def test_il_baselines_stability_summary_counts_the_evaluations_after_the_first_expert_level_one(tmp_path, capsys):
    """--summarize --stability: per CSV and algorithm, when each seed first scored >= the threshold, how many later
    evaluations also did, their minimum and how many seeds fell below it again (the step-0 row is left out)."""
    module = load_script("il_baselines")
    path = tmp_path / "variant_a.csv"
    rows = {0: [0.95, 0.2, 0.95, 1.0, 0.5],      # step 0 scores 0.95 (left out); first at 2k, then 1.0, 0.5
            1: [0.0, 0.1, 0.3, 0.4, 0.6]}        # never
    with open(path, "w") as fh:
        fh.write(",".join(module.FIELDS) + "\n")
        for seed, scores in rows.items():
            for i, score in enumerate(scores):
                fh.write(f"lsiq,perfect,{seed},{1000 * i},{1000 * i},1.0,0,0,{score},ref,run{seed}"
                         f"{'#final' if i == len(scores) - 1 else ''}\n")
    module.summarize_stability([path], 0.9)
    table = capsys.readouterr().out.splitlines()
    assert table[2] == "| variant_a | lsiq | perfect | 2 | 2k, never | 1/2 | 0.50 | 1/1 |", table


def test_il_baselines_reads_set_values_as_yaml_with_exponent_floats():
    """`--set actor_lr=1e-3`: YAML 1.1 reads 1e-3 as a string, which reached torch's optimizer as one."""
    parse = load_script("il_baselines").parse_value
    assert [parse(x) for x in ("1e-3", "3.0e-4", "false", "[64,64]", "mixture", "500")] == \
        [0.001, 0.0003, False, [64, 64], "mixture", 500]


def test_train_speed_groups_and_interval_rates(tmp_path):
    """`train_speed.py`: a group is DEVICE:COUNT[,...]; a run's rate skips the intervals up to its first update."""
    import argparse
    speed = load_script("train_speed")
    assert speed.parse_group("cpu:1,cuda:6") == [("cpu", 1), ("cuda", 6)]
    for bad in ("cpu", "cpu:0", "cuda:x", ":2"):
        with pytest.raises(argparse.ArgumentTypeError, match="DEVICE:COUNT"):
            speed.parse_group(bad)
    log = tmp_path / "log.csv"
    log.write_text("step,updates,steps_per_s\n1000,0,2000.0\n2000,1,1500.0\n3000,1001,60.0\n4000,2001,58.0\n")
    # 1000-2000 ended with the first update (mostly replay filling): only the intervals after it count
    assert speed.interval_rates(log) == [60.0, 58.0]
    assert speed.interval_rates(tmp_path / "missing.csv") == []


def run_start_mps(tmp_path, control: str | None, client_ok: bool = True) -> tuple[int, str, str]:
    """Source benchmarks/mps.sh and call start_mps with fake tools only on PATH: `control` is the body of a fake
    nvidia-cuda-mps-control (None: none on PATH), the fake python's client exits 0 or 1. Returns the exit status,
    the output and what the fake control was called with (arguments and stdin, one call per line)."""
    tools = tmp_path / "tools"
    tools.mkdir()
    for name in ("timeout", "mkdir", "tail", "tr", "cat"):
        (tools / name).symlink_to(shutil.which(name))
    calls = tmp_path / "calls.txt"
    if control is not None:
        fake = tools / "nvidia-cuda-mps-control"
        fake.write_text(f'#!/bin/bash\nstdin=$(cat)\necho "$* ${{stdin:-}}" >> {calls}\n{control}\n')
        fake.chmod(0o755)
    python = tools / "fake-python"
    python.write_text(f"#!/bin/bash\nexit {0 if client_ok else 1}\n")
    python.chmod(0o755)
    env = {"PATH": str(tools), "PYTHON": str(python), "CUDA_MPS_PIPE_DIRECTORY": str(tmp_path / "pipe"),
           "CUDA_MPS_LOG_DIRECTORY": str(tmp_path / "log")}
    done = subprocess.run([shutil.which("bash"), "-c", f"source {BENCHMARKS / 'mps.sh'}; start_mps"], env=env,
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
    return done.returncode, done.stdout + done.stderr, calls.read_text() if calls.exists() else ""


def test_start_mps_without_the_control_program_returns_3_and_says_so(tmp_path):
    status, out, _ = run_start_mps(tmp_path, control=None)
    assert status == 3 and "nvidia-cuda-mps-control not found" in out, out


def test_start_mps_stops_the_server_when_a_cuda_client_fails_under_it(tmp_path):
    status, out, calls = run_start_mps(tmp_path, control="exit 0", client_ok=False)
    assert status == 3 and "a CUDA client failed" in out, out
    assert calls.split("\n")[0].strip() == "-d" and "quit" in calls, calls   # started, then told to quit
    assert (tmp_path / "pipe").is_dir() and (tmp_path / "log").is_dir()


def test_start_mps_reports_the_server_when_a_client_runs(tmp_path):
    status, out, calls = run_start_mps(tmp_path, control='[ "$1" = -d ] || echo 4242')
    assert status == 0 and "MPS: server up (4242 )" in out, out
    assert "quit" not in calls, calls


def test_start_mps_returns_3_when_the_daemon_does_not_start(tmp_path):
    status, out, calls = run_start_mps(tmp_path, control="exit 1")
    assert status == 3 and "did not start" in out and calls.strip() == "-d", (out, calls)
