"""What a SAC-based imitation learner's policy and critic look like at a checkpoint, on its own evaluation episodes.

Written to diagnose LS-IQ's plateau on Hopper (benchmarks/RESULTS.md): does the policy fall, how far has its
std collapsed, how many of its mean actions sit at the action bounds, and does the critic's value of the
policy's states fall before the episode ends (i.e. does Q anticipate the fall)?

    python benchmarks/offpolicy_diagnostics.py runs/il/Hopper.run.perfect/lsiq/seed0 runs/il/Hopper.run.perfect/iqlearn/seed0

For each run directory (its `final_agent.pt`, else its latest `checkpoint.pt`): `--episodes` deterministic
evaluation episodes (the evaluation seeds of `loco_il.evaluation`), then on every visited state s:
  log_std    percentiles 5/50/95 of the policy's (clamped) log-std before tanh
  |a|>0.99   fraction of the deterministic action's components within 1 % of the bound
  entropy    -log pi(a~|s) averaged over s, a~ ~ pi(.|s) (nats; SAC's target for Hopper: |A| = 3 -> -3)
  V start/end the critic's soft value min_i Q_i(s, a~) - alpha log pi(a~|s), averaged over the first and the
             last `--window` states of the episodes that ended by falling (absorbing) before the horizon
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from loco_il.environments.registry import make  # noqa: E402
from loco_il.evaluation import evaluate_agent, load_run_agent, load_run_config, normalized  # noqa: E402


@torch.no_grad()
def diagnose(run_dir: str, episodes: int, window: int) -> dict:
    agent, source = load_run_agent(run_dir)
    cfg = load_run_config(run_dir)
    env = make(cfg["task_id"])
    result = evaluate_agent(agent, env, episodes, collect_obs=True)
    obs = torch.as_tensor(result["obs"], dtype=torch.float32)
    policy, sac = agent.policy_module, agent.sac
    mean, log_std = policy._mean_log_std(obs)
    action, logp = policy.sample(obs)
    v = sac.critic(obs, action).amin(0) - sac.alpha * logp
    starts = np.cumsum([0] + result["lengths"][:-1])
    falls = [(s, n) for s, n in zip(starts, result["lengths"]) if n < int(env.info.horizon)]
    v_start = [v[s:s + window].mean().item() for s, n in falls]
    v_end = [v[s + n - window:s + n].mean().item() for s, n in falls if n >= window]
    score, _, _ = normalized(cfg["task_id"], result["return_mean"])
    return {"run": run_dir, "source": source, "lengths": result["lengths"], "return": result["return_mean"],
            "normalized": score, "log_std_pct": np.percentile(log_std.numpy(), [5, 50, 95]),
            "saturated": (torch.tanh(mean).abs() > 0.99).float().mean().item(),
            "entropy": -logp.mean().item(), "alpha": float(sac.alpha),
            "v_start": float(np.mean(v_start)) if v_start else None,
            "v_end": float(np.mean(v_end)) if v_end else None, "falls": len(falls)}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dirs", nargs="+")
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--window", type=int, default=20, help="states averaged at the start and end of a fall")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    fmt = lambda x, digits=1: "n/a" if x is None else f"{x:.{digits}f}"  # noqa: E731
    for run_dir in args.run_dirs:
        d = diagnose(run_dir, args.episodes, args.window)
        print(f"{d['run']}\n  from {d['source']}")
        print(f"  episode lengths {d['lengths']}  return {d['return']:.1f}  normalized {fmt(d['normalized'], 3)}"
              f"  falls {d['falls']}/{len(d['lengths'])}")
        print(f"  log_std pct 5/50/95 {np.round(d['log_std_pct'], 2).tolist()}  |a|>0.99 {d['saturated']:.2f}"
              f"  entropy {d['entropy']:.1f}  alpha {d['alpha']:.3g}")
        print(f"  V(s) first {args.window} states {fmt(d['v_start'])}  last {args.window} before a fall {fmt(d['v_end'])}")


if __name__ == "__main__":
    main()
