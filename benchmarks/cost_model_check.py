"""The benchmark's cost model (`loco_il.benchmark.cost`) against the wall time of the runs it has finished.

For every finished run of a protocol (its `eval.json`, whose `wall_time` is the training's own clock summed over
resumes), prints the model's estimate of one run, the measured times of the cell's seeds and their ratio
(measured / model); then the median ratio per learner family. A ratio well below 1 means the model overestimates
(it counts evaluation episodes at the full horizon, so falls make runs shorter); above 1 usually means the runs
shared the 2-core machine with another run. Runs trained on a GPU (`device` other than cpu in their config.yaml)
are left out: the model is of CPU training.

    python benchmarks/cost_model_check.py [--protocol small]
"""
from __future__ import annotations

import argparse
import statistics
from collections import defaultdict

from loco_il.benchmark import cost
from loco_il.benchmark.cells import all_cells
from loco_il.benchmark.protocol import load_protocol
from loco_il.benchmark.seed_detail import DEFAULT_DEVICE, run_device
from loco_il.benchmark.status import finished_eval


def trained_on_cpu(run_dir) -> bool:
    return run_device(run_dir) == DEFAULT_DEVICE


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--protocol", default="small")
    args = parser.parse_args()
    proto = load_protocol(args.protocol)
    ratios: dict[str, list[float]] = defaultdict(list)
    print(f"{'cell':44s} {'model s':>8s}  measured s (per seed)   ratio")
    for cell in all_cells(proto):
        run_dirs = [cell.run_dir(proto.results_dir, s) for s in cell.seeds]
        walls = [e["wall_time"] for d in run_dirs
                 if (e := finished_eval(cell, d)) and "wall_time" in e and trained_on_cpu(d)]
        if not walls:
            continue
        model_s = cost.run_hours(proto, cell) * 3600
        ratio = statistics.mean(walls) / model_s
        ratios[cell.family.name].append(ratio)
        print(f"{cell.key:44s} {model_s:8.0f}  {', '.join(f'{w:.0f}' for w in walls):22s} {ratio:5.2f}")
    print()
    for family, values in ratios.items():
        print(f"{family}: median ratio {statistics.median(values):.2f} over {len(values)} cells "
              f"(range {min(values):.2f}-{max(values):.2f})")


if __name__ == "__main__":
    main()
