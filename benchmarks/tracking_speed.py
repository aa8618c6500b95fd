"""Env steps/s under the motion-tracking trainer's env, against the plain task env, per body.

For each body: steps/s of `TrackingEnv.step` in training mode (reference state initialization, stable-PD
conversion of the policy's targets, tracking reward, early termination) with zero policy actions, and of the plain
`LocoEnv.step` with the same number of steps and zero actions (the baseline), both in this process, in
alternating blocks so that machine load hits both alike; the ratio is the tracking env's cost over the plain env.

    python benchmarks/tracking_speed.py [--steps 3000] [--bodies Atlas UnitreeH1 ...]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from loco_il import LocoEnv
from loco_il.experts.tracking.controller import TrackingController
from loco_il.experts.tracking.env import TrackingEnv
from loco_il.experts.tracking.reference import build_reference
from loco_il.experts.tracking.settings import TrackingSettings
from loco_il.experts.tracking.trainer import task_target_speed

BODIES = ("Atlas", "UnitreeH1", "UnitreeG1", "Talos", "HumanoidTorque")


def _run(step, reset, steps: int) -> float:
    reset()
    start = time.perf_counter()
    for _ in range(steps):
        if step():
            reset()
    return time.perf_counter() - start


def measure(body: str, steps: int, blocks: int = 3) -> dict:
    env = LocoEnv.make(f"{body}.walk.perfect")
    reference = build_reference(env, target_speed=task_target_speed(env))
    controller = TrackingController.for_model(env.model, reference, TrackingSettings(), env.dt)
    tracking = TrackingEnv(env.task_id, controller.to_dict(), "train")
    zero = np.zeros(env.model.nu)
    seeds = iter(range(10 ** 6))
    t_track = t_plain = 0.0
    for _ in range(blocks):
        t_track += _run(lambda: any(tracking.step(zero)[2:4]), lambda: tracking.reset(seed=next(seeds)), steps)
        t_plain += _run(lambda: env.step(zero)[2], env.reset, steps)
    env.stop()
    tracking.close()
    n = steps * blocks
    return {"body": body, "tracking_steps_per_s": n / t_track, "plain_steps_per_s": n / t_plain,
            "ratio": t_plain / t_track, "reference_speed": reference.speed, "time_scale": reference.time_scale}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--bodies", nargs="+", default=list(BODIES))
    args = parser.parse_args()
    print(f"{'body':16s} {'tracking env':>14s} {'plain env':>11s} {'ratio':>6s}  reference")
    for body in args.bodies:
        r = measure(body, args.steps)
        print(f"{r['body']:16s} {r['tracking_steps_per_s']:10.0f} /s {r['plain_steps_per_s']:7.0f} /s {r['ratio']:6.2f}  "
              f"{r['reference_speed']:.2f} m/s (captured cycle x{r['time_scale']:.2f})", flush=True)


if __name__ == "__main__":
    main()
