"""A SAC-based learner's policy evaluated with its mean action and with sampled actions, side by side.

The long Hopper runs are scored with the deterministic policy (the Gaussian's mean through tanh), while
they train on, and their `train_return` logs, the sampled one. When the two disagree, a drop in the
evaluation curve need not be a drop of the learned behaviour. For each checkpoint: `--episodes` episodes
in each mode on the evaluation seeds of `loco_il.evaluation`, normalized score, mean length, falls.

    python benchmarks/eval_modes.py runs/il/Hopper.run.perfect/iqlearn/seed1
    python benchmarks/eval_modes.py runs/il/Hopper.run.perfect/lsiq_1critic/seed1 \
        --checkpoints copy_725k.pt copy_775k.pt
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from loco_il.environments.registry import make  # noqa: E402
from loco_il.evaluation import evaluate_agent, load_run_agent, load_run_config, normalized  # noqa: E402


def compare_modes(run_dir: str, checkpoint: str | None, episodes: int) -> dict:
    """Score, mean length and number of falls of the deterministic and the stochastic policy."""
    agent, source = load_run_agent(run_dir, checkpoint=checkpoint)
    cfg = load_run_config(run_dir)
    env = make(cfg["task_id"])
    horizon = int(env.info.horizon)
    out = {"source": source}
    for mode, det in (("mean", True), ("sampled", False)):
        res = evaluate_agent(agent, env, episodes, deterministic=det)
        score, _, _ = normalized(cfg["task_id"], res["return_mean"])
        lengths = res["lengths"]
        out[mode] = {"score": score, "length": sum(lengths) / len(lengths),
                     "falls": sum(n < horizon for n in lengths)}
    env.stop()
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", help="a train.py run dir (its config.yaml says how to build the agent)")
    parser.add_argument("--checkpoints", nargs="*", default=[None],
                        help="checkpoint files of this run to compare (default: the run's latest)")
    parser.add_argument("--episodes", type=int, default=10)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    header = "".join(f"{m + ' score':>16}{'length':>8}{'falls':>8}" for m in ("mean", "sampled"))
    print(f"{'checkpoint':<60}{header}")
    for ckpt in args.checkpoints:
        r = compare_modes(args.run_dir, ckpt, args.episodes)
        cells = "".join(f"{r[m]['score']:>16.2f}{r[m]['length']:>8.0f}{r[m]['falls']:>5}/{args.episodes:<2}"
                        for m in ("mean", "sampled"))
        print(f"{r['source'][-60:]:<60}{cells}", flush=True)


if __name__ == "__main__":
    main()
