"""The benchmark's cost model (`loco_il.benchmark.cost`) against the wall time of the runs it has finished.

Prints `loco_il.benchmark.cost_check.report` (per cell: the model's estimate of one run, each seed's measured
wall time, their ratio; then the median ratio per learner family). With `--results PATH`, writes the report into
PATH's `<!-- cost-model-check:<protocol> -->` block instead (RESULTS.md holds the `small` one; a test checks it is
what the committed logs give).

    python benchmarks/cost_model_check.py [--protocol small] [--results-dir DIR] [--results benchmarks/RESULTS.md]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from loco_il.benchmark import cost_check, doc_block
from loco_il.benchmark.protocol import load_protocol
from loco_il.utils.atomic import atomic_open


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--protocol", default="small")
    parser.add_argument("--results-dir", type=Path, default=None, metavar="DIR",
                        help="the runs to read (default: the protocol's results_dir)")
    parser.add_argument("--results", type=Path, default=None, metavar="PATH",
                        help="write the report into PATH's cost-model-check block instead of printing it")
    args = parser.parse_args(argv)
    proto = load_protocol(args.protocol)
    lines = cost_check.report(proto, args.results_dir)
    if args.results is None:
        print("\n".join(lines))
        return 0
    if not args.results.is_file():
        print(f"error: --results {args.results}: no such file; give the results page, e.g. "
              "--results benchmarks/RESULTS.md")
        return 2
    try:
        text = doc_block.replace_block(args.results.read_text(), cost_check.block_name(proto.name),
                                       cost_check.fenced(lines), where=str(args.results))
    except doc_block.MarkerError as err:
        print(f"error: {err}")
        return 2
    with atomic_open(args.results, "w") as fh:
        fh.write(text)
    print(f"wrote the cost model check of '{proto.name}' into {args.results}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
