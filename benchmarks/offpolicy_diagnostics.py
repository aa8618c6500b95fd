"""What a SAC-based imitation learner's policy and critic look like at a checkpoint, on its own evaluation episodes.

Written to diagnose LS-IQ's plateau on Hopper (benchmarks/RESULTS.md): does the policy fall, how far has its
std collapsed, how many of its mean actions sit at the action bounds, and does the critic's value of the
policy's states fall before the episode ends (i.e. does Q anticipate the fall)?

    python benchmarks/offpolicy_diagnostics.py runs/il/Hopper.run.perfect/lsiq/seed0 runs/il/Hopper.run.perfect/iqlearn/seed0
    python benchmarks/offpolicy_diagnostics.py runs/il/Hopper.run.perfect/lsiq_1critic/seed1 \
        --checkpoints kept_725k.pt kept_875k.pt

For each run directory (its `final_agent.pt`, else its latest `checkpoint.pt`): `--episodes` deterministic
evaluation episodes (the evaluation seeds of `loco_il.evaluation`), then on every visited state s:
  log_std    percentiles 5/50/95 of the policy's (clamped) log-std before tanh
  |a|>0.99   fraction of the deterministic action's components within 1 % of the bound
  entropy    -log pi(a~|s) averaged over s, a~ ~ pi(.|s) (nats; SAC's target for Hopper: |A| = 3 -> -3)
  V start/end the critic's soft value min_i Q_i(s, a~) - alpha log pi(a~|s), averaged over the first and the
             last `--window` states of the episodes that ended by falling (absorbing) before the horizon
  |pre-tanh| percentiles 5/50/95 of the deterministic action's components before tanh (tanh's slope there,
             1 - tanh^2, is what the actor's gradient is scaled by: ~1e-3 at 4, ~2e-4 at 5)
  Q gap      max over `--actions` uniformly random actions of min_i Q_i(s, a) minus min_i Q_i(s, mean action):
             median over all states and over the last `--window` states before falls, and the fraction of
             states where it exceeds 1 (half the per-step reward bound of LS-IQ). A large gap means the critic
             already prefers other actions and the actor has not followed it (an actor problem); a gap near 0
             means the policy sits at the critic's maximum (whatever is wrong is in the critic); also shown with
             the mean V over the `--window` states starting 200, 100 and 50 steps before each fall
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


def q_gap(critic, obs: torch.Tensor, mean_action: torch.Tensor, n_actions: int, seed: int = 0,
          chunk: int = 64) -> torch.Tensor:
    """Per state: max over `n_actions` uniform random actions in [-1, 1]^d of min-head Q, minus that of mean_action."""
    gen = torch.Generator().manual_seed(seed)
    rand = torch.rand(n_actions, mean_action.shape[1], generator=gen) * 2 - 1
    best = []
    for i in range(0, len(obs), chunk):
        o = obs[i:i + chunk]
        rows = o.repeat_interleave(n_actions, 0)
        best.append(critic(rows, rand.repeat(len(o), 1)).amin(0).view(len(o), n_actions).amax(1))
    return torch.cat(best) - critic(obs, mean_action).amin(0)


@torch.no_grad()
def diagnose(run_dir: str, episodes: int, window: int, n_actions: int = 256, checkpoint: str | None = None) -> dict:
    agent, source = load_run_agent(run_dir, checkpoint=checkpoint)
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
    gap = q_gap(sac.critic, obs, torch.tanh(mean), n_actions)
    gap_end = torch.cat([gap[s + n - window:s + n] for s, n in falls if n >= window] or [torch.zeros(0)])
    before_fall = {}   # steps before the fall -> (mean V, median Q gap) over the `window` states from there on
    for back in (200, 100, 50):
        rows = torch.cat([torch.arange(s + n - back, s + n - back + window) for s, n in falls if n >= back]
                         or [torch.zeros(0, dtype=torch.long)])
        if len(rows):
            before_fall[back] = (v[rows].mean().item(), gap[rows].median().item())
    score, _, _ = normalized(cfg["task_id"], result["return_mean"])
    return {"run": run_dir, "source": source, "lengths": result["lengths"], "return": result["return_mean"],
            "normalized": score, "log_std_pct": np.percentile(log_std.numpy(), [5, 50, 95]),
            "saturated": (torch.tanh(mean).abs() > 0.99).float().mean().item(),
            "entropy": -logp.mean().item(), "alpha": float(sac.alpha),
            "v_start": float(np.mean(v_start)) if v_start else None,
            "v_end": float(np.mean(v_end)) if v_end else None, "falls": len(falls),
            "pre_tanh_pct": np.percentile(mean.abs().numpy(), [5, 50, 95]),
            "gap_median": gap.median().item(), "gap_over_1": (gap > 1).float().mean().item(),
            "gap_end_median": gap_end.median().item() if len(gap_end) else None, "before_fall": before_fall}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dirs", nargs="+")
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--window", type=int, default=20, help="states averaged at the start and end of a fall")
    parser.add_argument("--actions", type=int, default=256, help="random actions per state for the Q gap")
    parser.add_argument("--checkpoints", nargs="*", default=[None],
                        help="with one run dir: kept checkpoint files of it to diagnose instead of its latest")
    args = parser.parse_args(argv)
    if args.checkpoints != [None] and len(args.run_dirs) != 1:
        parser.error("--checkpoints needs exactly one run dir")
    torch.set_num_threads(1)
    fmt = lambda x, digits=1: "n/a" if x is None else f"{x:.{digits}f}"  # noqa: E731
    for run_dir, ckpt in [(r, c) for r in args.run_dirs for c in args.checkpoints]:
        d = diagnose(run_dir, args.episodes, args.window, args.actions, ckpt)
        print(f"{d['run']}\n  from {d['source']}")
        print(f"  episode lengths {d['lengths']}  return {d['return']:.1f}  normalized {fmt(d['normalized'], 3)}"
              f"  falls {d['falls']}/{len(d['lengths'])}")
        print(f"  log_std pct 5/50/95 {np.round(d['log_std_pct'], 2).tolist()}  |a|>0.99 {d['saturated']:.2f}"
              f"  entropy {d['entropy']:.1f}  alpha {d['alpha']:.3g}")
        print(f"  V(s) first {args.window} states {fmt(d['v_start'])}  last {args.window} before a fall {fmt(d['v_end'])}")
        print(f"  |pre-tanh| pct 5/50/95 {np.round(d['pre_tanh_pct'], 2).tolist()}  Q gap median {d['gap_median']:.2f}"
              f" (> 1 on {d['gap_over_1']:.2f} of states)  last {args.window} before a fall {fmt(d['gap_end_median'], 2)}")
        if d["before_fall"]:
            print("  V / Q gap from k steps before a fall: " + "  ".join(
                f"{k}: {v:.1f} / {g:.2f}" for k, (v, g) in d["before_fall"].items()))


if __name__ == "__main__":
    main()
