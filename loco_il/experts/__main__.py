"""Command line: train and evaluate experts (PPO by default, SAC with algo=sac, motion tracking with algo=tracking).

    python -m loco_il.experts train task=Hopper.run total_steps=2000000 num_envs=16 seed=0 out_dir=runs/hopper
    python -m loco_il.experts train task=HalfCheetah.run algo=sac total_steps=1000000 device=cuda
    python -m loco_il.experts eval path=runs/hopper/best.pt episodes=10
    python -m loco_il.experts eval path=runs/hopper/evals episodes=30     # every kept policy; the most reliable
    python -m loco_il.experts train task=Atlas.walk algo=tracking        # a motion-tracking expert (PPO)
    python -m loco_il.experts eval path=runs/experts/Atlas.walk/seed0/best.pt episodes=100 starts=both
    python -m loco_il.experts slim path=runs/ant/checkpoint.pt out=ant_checkpoint_noreplay.pt
    python -m loco_il.experts tune path=runs/tracking/Atlas.walk/seed0/evals/step_005001216.pt out=expert.pt \
        speed_gain=1.04 speed_gain_time=4

`train` is a Hydra app (configs/train.yaml with configs/algo/<algo>.yaml, then the `<algo>:` section of
configs/body/<Body>.yaml when it exists); re-running the same command with the same out_dir resumes from
out_dir/checkpoint.pt. Its last output line is a JSON
summary (final evaluation return mean and std, env steps, wall time). `eval` prints one JSON line per expert
file; with `path=<folder>` (e.g. a run's `evals/`, written with `keep_eval_policies=true`) it evaluates every
file in it on the same episodes and names the most reliable one (fewest terminated episodes).
`slim` copies a checkpoint without its replay memory (a resumed run refills it); copy the result to
<out_dir>/checkpoint.pt to go on from it. `tune` writes a copy of a tracking expert with other deployment settings
(the phase clock's: `TrackingSettings.DEPLOYMENT_FIELDS`).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import hydra
from omegaconf import DictConfig, OmegaConf

CONFIG_DIR = str(Path(__file__).resolve().parent / "configs")
USAGE = __doc__


def body_config_path(task: str) -> Path:
    body = str(task).split(".")[0].split("-")[0]
    return Path(CONFIG_DIR) / "body" / f"{body}.yaml"


def _cli_overrides() -> list[str]:
    """The plain key=value overrides of this Hydra run (to re-apply above the per-body file)."""
    from hydra.core.hydra_config import HydraConfig
    out = []
    for item in HydraConfig.get().overrides.task:
        if item.startswith("~"):
            continue
        out.append(item.lstrip("+"))
    return out


def compose_train_config(cfg: DictConfig, cli_overrides: list[str]) -> dict[str, Any]:
    """train.yaml + algo/<algo>.yaml <- the `<algo>:` section of configs/body/<Body>.yaml <- command line,
    resolved to a plain dict."""
    cfg = OmegaConf.create(OmegaConf.to_container(cfg, resolve=False))
    body_file = body_config_path(cfg.task)
    if body_file.exists():
        section = OmegaConf.load(body_file).get(cfg.algo)
        if section:
            plain_overrides = [o for o in cli_overrides if not o.startswith("algo=")]
            cfg = OmegaConf.merge(cfg, section, OmegaConf.from_dotlist(plain_overrides))
    return OmegaConf.to_container(cfg, resolve=True)


TRAINERS = {"ppo": "loco_il.experts.ppo:PPOTrainer", "sac": "loco_il.experts.sac:SACTrainer",
            "tracking": "loco_il.experts.tracking.trainer:TrackingTrainer"}


def trainer_class(algo: str):
    """The trainer for `algo` (imported on use: the trainers pull in the env stack)."""
    import importlib
    if algo not in TRAINERS:
        raise SystemExit(f"unknown algo={algo!r}; one of {sorted(TRAINERS)}")
    module, name = TRAINERS[algo].split(":")
    return getattr(importlib.import_module(module), name)


@hydra.main(config_path=CONFIG_DIR, config_name="train", version_base=None)
def train_main(cfg: DictConfig) -> None:
    plain = compose_train_config(cfg, _cli_overrides())
    summary = trainer_class(plain["algo"])(plain).train()
    if summary["stopped_by_signal"]:
        raise SystemExit(130)    # the shell convention for "interrupted": scripts must not go on as if it finished


@hydra.main(config_path=CONFIG_DIR, config_name="eval", version_base=None)
def eval_main(cfg: DictConfig) -> None:
    """One JSON line per expert file; `path` may be a folder (e.g. a run's `evals/`): then every `*.pt` in it is
    evaluated on the same episodes and a last line names the most reliable one (fewest terminated episodes,
    i.e. ended by a fall or by leaving the healthy range rather than truncated at the horizon, then highest
    mean return)."""
    import numpy as np

    from loco_il.experts.policy import load_expert
    from loco_il.experts.vec import evaluate_episodes, make_vec_env
    root = Path(cfg.path)
    if not root.exists():
        raise SystemExit(f"path={root}: no such expert file or folder")
    paths = sorted(root.glob("*.pt")) if root.is_dir() else [root]
    if not paths:
        raise SystemExit(f"no expert files (*.pt) in {root}")
    results, envs_by_task = [], {}
    try:
        for path in paths:
            expert = load_expert(path)
            task = cfg.task or expert.metadata.get("task_id")
            if not task:
                raise SystemExit(f"{path} names no task_id; pass task=<Task-ID>")
            if hasattr(expert, "start_episode"):    # keeps a clock: episodes one by one, as datasets record them
                result = _evaluate_env_expert(expert, path, task, int(cfg.episodes), int(cfg.seed), str(cfg.starts))
                results.append(result)
                print(json.dumps(result), flush=True)
                continue
            if task not in envs_by_task:
                envs_by_task[task] = make_vec_env(task, max(1, int(cfg.num_envs)), cfg["async"])
            envs = envs_by_task[task]
            rng = np.random.default_rng(cfg.seed)
            act = (lambda o: expert.act(o, deterministic=False, rng=rng)) if cfg.stochastic else expert
            returns, lengths, terminated = evaluate_episodes(act, envs, int(cfg.episodes), seed=int(cfg.seed))
            result = {"path": str(path), "task_id": task, "episodes": int(len(returns)),
                      "return_mean": round(float(returns.mean()), 2), "return_std": round(float(returns.std()), 2),
                      "return_min": round(float(returns.min()), 2), "length_mean": round(float(lengths.mean()), 1),
                      "terminated": int(terminated.sum()),
                      "returns": [round(float(r), 2) for r in returns],
                      "training_steps": expert.metadata.get("training_steps"),
                      "stored_eval_return": expert.metadata.get("eval_return"), "checksum": expert.checksum()}
            results.append(result)
            print(json.dumps(result), flush=True)
    finally:
        for envs in envs_by_task.values():
            envs.close()
    if root.is_dir():
        best = min(results, key=lambda r: (r["terminated"], -r["return_mean"]))
        print(json.dumps({"most_reliable": best["path"], "terminated": best["terminated"],
                          "return_mean": best["return_mean"], "return_std": best["return_std"],
                          "evaluated": len(results)}), flush=True)


STARTS = ("env", "reference", "both")


def _evaluate_env_expert(expert: Any, path: Path, task: str, episodes: int, seed: int,
                         starts: str = "both") -> dict[str, Any]:
    """An expert with a `start_episode` hook (e.g. a `TrackingExpert`), episode by episode as datasets record them.

    `starts`: "env" (the task env's own start states), "reference" (states of the expert's reference motion at
    seeded uniform phases; experts without a reference refuse) or "both" (the first half of the episodes from the
    env's starts, the rest from the reference). Episode k of a part starts from `episode_seeds(seed, n)[k]`.
    Reports returns, terminations (falls) and the mean forward speed against the task's target speed."""
    import numpy as np

    from loco_il.environments.episodes import evaluate_task
    from loco_il.environments.registry import make
    if starts not in STARTS:
        raise SystemExit(f"starts must be one of {', '.join(STARTS)}; got {starts!r}")
    sampler = getattr(expert, "reference_start_sampler", None)
    if starts != "env" and sampler is None:
        raise SystemExit(f"{path} has no reference motion; use starts=env")
    n_env = {"env": episodes, "reference": 0, "both": (episodes + 1) // 2}[starts]
    parts = [evaluate_task(task, expert, n, seed, details=True, env_kwargs=kwargs)
             for n, kwargs in ((n_env, {}), (episodes - n_env, {"init_state_sampler": sampler and sampler()}))
             if n > 0]
    keys = ("returns", "lengths", "terminated", "forward_speed")
    res = {k: sum((p[k] for p in parts), []) for k in keys}
    # the bar's two kinds of start separately: a walker can track from reference states and still fall from standing
    by_start = {name: _start_summary(p) for name, p in zip(("env_starts", "reference_starts"), parts) if p}
    if starts == "reference":
        by_start = {"reference_starts": by_start.pop("env_starts")}
    probe = make(task)
    target = getattr(probe.task.reward, "target", None)
    probe.stop()
    returns, speeds = np.array(res["returns"]), np.array(res["forward_speed"])
    return {"path": str(path), "task_id": task, "episodes": episodes, "seed": seed, "starts": starts,
            "env_start_episodes": n_env,
            "return_mean": round(float(returns.mean()), 2), "return_std": round(float(returns.std()), 2),
            "return_min": round(float(returns.min()), 2), "length_mean": round(float(np.mean(res["lengths"])), 1),
            "terminated": int(np.sum(res["terminated"])), "forward_speed_mean": round(float(speeds.mean()), 3),
            "forward_speed_std": round(float(speeds.std()), 3), "target_speed": target,
            **by_start, "returns": [round(float(r), 2) for r in returns],
            "training_steps": expert.metadata.get("training_steps"),
            "stored_eval_return": expert.metadata.get("eval_return"), "checksum": expert.checksum()}


def _start_summary(part: dict[str, Any]) -> dict[str, Any]:
    """Episodes, mean return, falls and mean forward speed of one kind of start."""
    import numpy as np
    return {"episodes": len(part["returns"]), "return_mean": round(float(np.mean(part["returns"])), 2),
            "terminated": int(np.sum(part["terminated"])),
            "forward_speed_mean": round(float(np.mean(part["forward_speed"])), 3)}


def slim_main(argv: list[str]) -> None:
    from loco_il.experts.trainer import slim_checkpoint
    args = dict(a.split("=", 1) for a in argv if "=" in a)
    if set(args) != {"path", "out"} or len(args) != len(argv):
        raise SystemExit("usage: python -m loco_il.experts slim path=<checkpoint.pt> out=<new file>")
    print(json.dumps({"path": args["path"], "out": args["out"], **slim_checkpoint(args["path"], args["out"])}), flush=True)


def tune_main(argv: list[str]) -> None:
    from loco_il.experts.policy import load_expert
    from loco_il.experts.tracking.expert import TrackingExpert
    args = dict(a.split("=", 1) for a in argv if "=" in a)
    path, out = args.pop("path", None), args.pop("out", None)
    if not path or not out or not args or len(argv) != len(args) + 2:
        raise SystemExit("usage: python -m loco_il.experts tune path=<tracking expert.pt> out=<new file> "
                         "<setting>=<value> ... (e.g. speed_gain=1.04 speed_gain_time=4)")
    if not Path(path).is_file():
        raise SystemExit(f"[loco_il] error: no expert file {path}")
    expert = load_expert(path)
    if not isinstance(expert, TrackingExpert):
        raise SystemExit(f"{path} is not a tracking expert; only tracking experts have deployment settings")
    try:
        tuned = expert.with_settings(**{k: None if v.lower() in ("none", "null") else v for k, v in args.items()})
    except ValueError as err:
        raise SystemExit(f"[loco_il] error: {err}") from None
    print(json.dumps({"path": path, "out": out, "changes": args, "checksum": tuned.save(out)}), flush=True)


def main(argv: list[str] | None = None) -> None:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in ("slim", "tune"):
        (slim_main if argv[0] == "slim" else tune_main)(argv[1:])
        return
    if not argv or argv[0] not in ("train", "eval"):
        print(USAGE, file=sys.stderr)
        raise SystemExit(0 if argv and argv[0] in ("-h", "--help") else 2)
    command = argv.pop(0)
    sys.argv = [sys.argv[0]] + argv
    (train_main if command == "train" else eval_main)()


if __name__ == "__main__":
    main()
