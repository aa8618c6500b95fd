"""Scoring a `train.py` run dir: its config, its trained agent (`final_agent.pt` or a checkpoint), a fresh
evaluation of it (`python -m loco_il.evaluation run_dir=...`) and a video of one episode (`... record`)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from loco_il.experiment.scoring import evaluate_agent, normalized, trajectory_similarity


def load_run_config(run_dir: str | Path) -> dict:
    run_dir = Path(run_dir)
    path = run_dir / "config.yaml"
    if not path.is_file():
        raise FileNotFoundError(f"{run_dir} is not a train.py run dir: it has no config.yaml")
    import yaml
    with open(path) as fh:
        return yaml.safe_load(fh)


class RunFileError(ValueError):
    """A run file that cannot be used (damaged, truncated, not a loco_il file): one-line message naming it."""


def load_final_agent(path: str | Path, device: str = "cpu") -> Any:
    """`final_agent.pt`, verified against `final_agent.pt.sha256` when the run recorded one."""
    from loco_il.algorithms.common.agent_base import ILAgent
    from loco_il.utils.hashing import ChecksumMismatchError, verify_sidecar
    try:
        verify_sidecar(path)
        return ILAgent.load(path, device=device)
    except ChecksumMismatchError as exc:
        raise RunFileError(f"{exc}; delete it to score the run's checkpoint.pt instead") from None
    except (OSError, RuntimeError, EOFError, ValueError, KeyError) as exc:
        raise RunFileError(f"cannot read {path} ({type(exc).__name__}: {str(exc).splitlines()[0][:120]}): the file is "
                           f"damaged or truncated; delete it to score the run's checkpoint.pt instead") from None


def load_run_agent(run_dir: str | Path, device: str = "cpu",
                   checkpoint: str | Path | None = None) -> tuple[Any, str]:
    """The trained agent of a run (`final_agent.pt`, else the latest `checkpoint.pt`) and which file it was.
    `checkpoint`: a train.py checkpoint file of this run to load instead (e.g. a copy kept from an earlier step).
    Files with a recorded sha256 are verified first (`RunFileError` / `CheckpointError` naming a damaged one)."""
    import torch

    from loco_il.algorithms import factory
    from loco_il.environments.registry import make
    from loco_il.experiment.checkpoint import has_checkpoint, load_checkpoint, load_run_checkpoint
    run_dir = Path(run_dir)
    if checkpoint is not None:
        ckpt_path = Path(checkpoint)
        if not ckpt_path.is_file():
            raise FileNotFoundError(f"checkpoint {ckpt_path} does not exist")
        ckpt = load_checkpoint(ckpt_path)
    else:
        final = run_dir / "final_agent.pt"
        if final.is_file():
            return load_final_agent(final, device=device), str(final)
        if not has_checkpoint(run_dir):
            raise FileNotFoundError(f"{run_dir} has neither final_agent.pt nor checkpoint.pt (was the run started?)")
        ckpt, ckpt_path = load_run_checkpoint(run_dir, repair=False)
    cfg = load_run_config(run_dir)
    env = make(cfg["task_id"])
    torch.manual_seed(int(cfg.get("seed", 0)))
    agent = factory.build_agent(cfg["algo"]["name"], env.info, cfg["algo"], seed=cfg.get("seed"), device=device)
    agent.load_state_dict(ckpt["agent"])
    env.stop()
    return agent, f"{ckpt_path} (step {ckpt['counters'].get('step')}, training not finished)"


def expert_observations(cfg: Mapping[str, Any], env: Any) -> tuple[np.ndarray | None, np.ndarray | None, str | None]:
    """(held-out expert obs, training expert obs, note) of a run's dataset settings."""
    from loco_il.datasets.loading import load_datasets
    try:
        train, test = load_datasets(env, cfg.get("dataset") or {})
    except Exception as exc:  # noqa: BLE001 - similarity is optional; say why it is missing
        return None, None, f"no trajectory similarity: the dataset could not be loaded ({type(exc).__name__}: {exc})"
    ref = test if test is not None and test.n_transitions else train
    return ref.obs, (train.obs if ref is not train else None), None


def evaluate_run(run_dir: str | Path, episodes: int = 10, seed: int | None = None, similarity: bool = True,
                 max_points: int = 1000, deterministic: bool = True) -> dict[str, Any]:
    """Score a run dir's trained policy; the dict has the keys of the run's `eval.json`."""
    from loco_il.environments.registry import task_key
    from loco_il.environments.registry import make
    cfg = load_run_config(run_dir)
    agent, source = load_run_agent(run_dir)
    env = make(cfg["task_id"])
    ev_cfg = cfg.get("eval") or {}
    seed = int(ev_cfg.get("seed", 1000)) if seed is None else int(seed)
    res = evaluate_agent(agent, env, episodes, seed, deterministic, collect_obs=similarity)
    score, note, base = normalized(cfg["task_id"], res["return_mean"])
    out = {"task_id": env.task_id, "task": task_key(env.task_id) + (".pomdp" if env.task_id.endswith(".pomdp") else ""),
           "dataset_type": env.dataset_type, "algorithm": cfg["algo"]["name"], "name": cfg.get("name"),
           "seed": cfg.get("seed"), "agent_file": source, **{k: v for k, v in res.items() if k != "obs"},
           "normalized_score": score, "normalized_score_note": note, "baseline": base}
    if similarity:
        e_obs, tr_obs, sim_note = expert_observations(cfg, env)
        out["similarity"] = (trajectory_similarity(res["obs"], e_obs, tr_obs, max_points) if e_obs is not None
                             else None)
        if sim_note:
            out["similarity_note"] = sim_note
    env.stop()
    return out


def record_run(run_dir: str | Path, out: str | Path, seed: int = 0, max_steps: int | None = None) -> dict:
    """Write an mp4 of one deterministic episode of a run's policy."""
    from loco_il.environments.registry import make
    from loco_il.environments.rendering import record_episode
    cfg = load_run_config(run_dir)
    agent, source = load_run_agent(run_dir)
    agent.deterministic = True
    agent.policy_module.eval()
    env = make(cfg["task_id"], seed=seed)
    try:
        result = record_episode(env, agent.draw_action, out, max_steps=max_steps)
    finally:
        env.stop()
    result["agent_file"] = source
    return result


__all__ = ["load_run_config", "RunFileError", "load_final_agent", "load_run_agent", "expert_observations",
           "evaluate_run", "record_run"]
