"""Score or film a trained policy of a `train.py` run dir.

    python -m loco_il.evaluation run_dir=<run dir> [episodes=10] [seed=<eval seed>] [similarity=true]
                                 [max_points=1000] [out=<file.json>]
    python -m loco_il.evaluation record run_dir=<run dir> out=video.mp4 [seed=0] [max_steps=<n>]

The first form prints a Markdown table and one JSON line (mean ± std return with the task's reward, the
normalized score against the random and expert baselines of loco_il/datasets/baselines.yaml, and the
trajectory similarity to the held-out expert data); `out=` also writes the JSON to a file. It uses
`final_agent.pt`, or the latest `checkpoint.pt` of an unfinished run. The second writes an mp4 of one
deterministic episode (headless rendering: MUJOCO_GL=egl, the default, or osmesa).
"""
from __future__ import annotations

import json
import os
import sys

USAGE = __doc__

_BOOL = {"true": True, "1": True, "yes": True, "false": False, "0": False, "no": False}


class UsageError(ValueError):
    """Command-line misuse: printed as one line, exit status 2."""


def _int_arg(args: dict[str, str], key: str, default: int | None, minimum: int) -> int | None:
    """`key`'s value as an integer >= `minimum` (a one-line `UsageError` naming the key otherwise)."""
    if key not in args:
        return default
    try:
        value = int(args[key])
    except ValueError:
        value = None
    if value is None or value < minimum:
        raise UsageError(f"{key}={args[key]}: expected an integer >= {minimum} (e.g. {key}={max(minimum, 10)})")
    return value


def _bool_arg(args: dict[str, str], key: str) -> bool:
    value = args.get(key, "true").lower()
    if value not in _BOOL:
        raise UsageError(f"{key}={args[key]}: expected true or false")
    return _BOOL[value]


def parse_args(argv: list[str]) -> tuple[str, dict[str, str]]:
    command = "score"
    if argv and "=" not in argv[0] and not argv[0].startswith("-"):
        command = argv.pop(0)
    if command not in ("score", "record"):
        raise UsageError(f"unknown command {command!r}; expected 'record' or key=value arguments (see --help)")
    args = {}
    for item in argv:
        if item in ("-h", "--help"):
            print(USAGE)
            raise SystemExit(0)
        if "=" not in item:
            raise UsageError(f"expected key=value, got {item!r} (see --help)")
        key, value = item.split("=", 1)
        args[key.lstrip("+")] = value
    allowed = {"score": {"run_dir", "episodes", "seed", "similarity", "max_points", "out", "deterministic"},
               "record": {"run_dir", "out", "seed", "max_steps"}}[command]
    unknown = sorted(set(args) - allowed)
    if unknown:
        raise UsageError(f"unknown argument(s) {unknown} for {command!r}; accepted: {sorted(allowed)}")
    if "run_dir" not in args:
        raise UsageError("run_dir=<run dir> is required (see --help)")
    return command, args


def _reexec_with_gl_backend(argv: list[str]) -> None:
    """MuJoCo picks its OpenGL backend from MUJOCO_GL when `mujoco` is first imported, which importing the
    `loco_il` package (before this module runs) already did; without MUJOCO_GL, run again with egl."""
    if "MUJOCO_GL" not in os.environ and "mujoco" in sys.modules:
        env = dict(os.environ, MUJOCO_GL="egl")
        os.execve(sys.executable, [sys.executable, "-m", "loco_il.evaluation", *argv], env)


def main(argv: list[str] | None = None) -> int:
    import torch
    torch.set_num_threads(1)
    from loco_il.evaluation import RunFileError, evaluate_run, format_eval_table, record_run
    from loco_il.experiment.checkpoint import CheckpointError
    from loco_il.utils.fileio import jsonable, write_json
    try:
        command, args = parse_args(list(sys.argv[1:] if argv is None else argv))
        if command == "record":
            seed, max_steps = _int_arg(args, "seed", 0, 0), _int_arg(args, "max_steps", None, 1)
            if argv is None:
                _reexec_with_gl_backend(sys.argv[1:])
            out = args.get("out", "video.mp4")
            res = record_run(args["run_dir"], out, seed=seed, max_steps=max_steps)
            print(f"wrote {res['path']}: return {res['return']:.2f} over {res['steps']} steps "
                  f"(policy: {res['agent_file']})")
            return 0
        episodes, seed = _int_arg(args, "episodes", 10, 1), _int_arg(args, "seed", None, 0)
        max_points = _int_arg(args, "max_points", 1000, 2)
        similarity, deterministic = _bool_arg(args, "similarity"), _bool_arg(args, "deterministic")
        res = evaluate_run(args["run_dir"], episodes=episodes, seed=seed, similarity=similarity,
                           max_points=max_points, deterministic=deterministic)
    except (UsageError, FileNotFoundError, RunFileError, CheckpointError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    res["steps"] = _trained_steps(args["run_dir"])
    print(format_eval_table([res]))
    if res.get("similarity_note"):
        print(f"Note: {res['similarity_note']}")
    print(json.dumps(jsonable(res)))
    if "out" in args:
        write_json(args["out"], res)
    return 0


def _trained_steps(run_dir: str) -> int | None:
    """Steps the scored policy was trained for: eval.json's, else the step of the run's latest checkpoint."""
    from pathlib import Path

    from loco_il.experiment.checkpoint import read_checkpoint_summary
    path = Path(run_dir) / "eval.json"
    if path.is_file():
        return json.loads(path.read_text()).get("steps")
    summary = read_checkpoint_summary(run_dir)
    return summary["step"] if summary else None


if __name__ == "__main__":
    raise SystemExit(main())
