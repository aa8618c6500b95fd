"""Quality of the quadrupeds' `real` data (the simulated trot): speed, heading, foot slip, kept episodes.

    python benchmarks/gait_quality.py [--episodes 10] [--steps 1000]
"""
from __future__ import annotations

import argparse
import time

from loco_il import LocoEnv
from loco_il.datasets.gait import generate_episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--steps", type=int, default=1000, help="recorded steps per episode (after 1 s warm-up)")
    args = parser.parse_args()
    print(f"{'task':26s}{'speed m/s':>10s}{'dir err':>9s}{'head err':>9s}{'slip m/s':>9s}{'slip p90':>9s}"
          f"{'max tilt':>9s}{'reward':>8s}{'kept':>8s}{'s':>7s}")
    for task in ("UnitreeA1.simple.real", "UnitreeA1.hard.real", "UnitreeGo1.simple.real", "UnitreeGo1.hard.real"):
        start = time.perf_counter()
        _, s = generate_episodes(LocoEnv.make(task), n_episodes=args.episodes, seed=0, episode_steps=args.steps)
        print(f"{task:26s}{s['mean_speed']:>10.3f}{s['mean_direction_error_deg']:>8.2f}°"
              f"{s['mean_heading_error_deg']:>8.2f}°{s['mean_foot_slip']:>9.3f}{s['mean_foot_slip_p90']:>9.3f}"
              f"{s['max_tilt_deg']:>8.1f}°{s['mean_reward']:>8.3f}{s['episodes']:>4d}/{s['attempts']:<3d}"
              f"{time.perf_counter() - start:>7.1f}", flush=True)


if __name__ == "__main__":
    main()
