"""The expert data of a run: the `dataset` group of `train.py`'s config as `create_dataset` calls.

Used by the training loop (`loco_il.experiment.runner`) and by the evaluation of a run dir
(`loco_il.evaluation.runs`), which must load the same splits.
"""
from __future__ import annotations

from typing import Any, Mapping

from loco_il.datasets import Trajectories, create_dataset


def dataset_kwargs(dcfg: Mapping[str, Any]) -> dict[str, Any]:
    """Keyword arguments of `create_dataset` (besides env and split) from the config's `dataset` group."""
    kwargs = {k: dcfg[k] for k in ("n_episodes", "expert_path", "workers") if dcfg.get(k) is not None}
    if dcfg.get("regenerate"):   # generate again and replace the cached copy
        kwargs["regenerate"] = True
    kwargs.update({k: v for k, v in (dcfg.get("provider_kwargs") or {}).items()})
    return dict(n_trajectories=dcfg.get("n_trajectories"), portion=tuple(dcfg.get("portion") or (0.0, 0.75)),
                seed=int(dcfg.get("split_seed", 0)), generation_seed=int(dcfg.get("generation_seed", 0)),
                verbose=bool(dcfg.get("verbose", True)), **kwargs)


def load_datasets(env: Any, dcfg: Mapping[str, Any]) -> tuple[Trajectories, Trajectories | None]:
    """(train, test) expert data of `env`'s Task-ID; test is None when the split leaves no test episodes."""
    common = dataset_kwargs(dcfg)
    train = create_dataset(env, split="train", **common)
    portion = common["portion"]
    test = None
    if portion[1] - portion[0] < 1.0:
        try:   # the train split's call already regenerated the pool (or kept it in memory): not again
            test = create_dataset(env, split="test", **{**common, "verbose": False, "regenerate": False})
        except Exception:  # noqa: BLE001 - a pool too small for a test split: similarity uses train
            test = None
    return train, test


__all__ = ["dataset_kwargs", "load_datasets"]
