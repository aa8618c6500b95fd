"""Convert between :class:`Trajectories` and Minari datasets.

Needs the optional ``minari`` package with its HDF5 backend
(``pip install loco_il[datasets]``, which pulls ``minari`` and ``h5py``).
Minari is imported inside the functions only.

Mapping (Minari episode of T steps <-> T transitions of one episode):

* ``observations`` (T + 1, obs_dim) <-> ``obs`` of the T transitions followed
  by the ``next_obs`` of the final one. So a dataset can be written only if
  ``next_obs[t] == obs[t + 1]`` inside every episode (true for anything
  recorded by stepping an env); otherwise :class:`DatasetError` is raised.
* ``actions`` (T, act_dim) <-> ``actions``.
* ``rewards`` (T,) <-> ``rewards``.
* ``terminations`` <-> ``absorbing``.
* ``truncations`` <-> ``last & ~absorbing`` (episode ended by time limit or by
  the end of the recording); reading back, ``last = terminations | truncations``
  and the final step of every Minari episode is always marked last.

**States-only datasets** (``actions is None``, the ``real`` type): Minari
requires actions, and zero placeholders would look like real actions to
other Minari users, so :func:`to_minari` refuses them with a
:class:`DatasetError`. Convert them to ``.npz`` with
:meth:`Trajectories.save` instead.

The loco_il ``info`` dict is stored as JSON in the Minari metadata under the
key ``"loco_il_info"`` and restored by :func:`from_minari`; a dataset made by
another tool gets an info built from its metadata (``source =
"minari:<dataset_id>"``, ``dataset_type = None`` unless given).
"""

from __future__ import annotations

import json
import warnings
from typing import Any, Mapping, Optional

import numpy as np

from loco_il.datasets.trajectory import DatasetError, Trajectories, _info_to_json

#: Minari metadata key holding the loco_il info as a JSON string.
INFO_METADATA_KEY = "loco_il_info"

_INSTALL_HINT = "the minari converter needs the optional dependencies: pip install loco_il[datasets]"


def _import_minari():
    try:
        import minari
    except ImportError as exc:
        raise ImportError(f"{_INSTALL_HINT} ({exc})") from exc
    return minari


def to_minari(
    trajs: Trajectories,
    dataset_id: str,
    *,
    env: Any = None,
    observation_space: Any = None,
    action_space: Any = None,
    algorithm_name: Optional[str] = None,
    author: Optional[str] = None,
    author_email: Optional[str] = None,
    code_permalink: Optional[str] = None,
    description: Optional[str] = None,
    overwrite: bool = False,
):
    """Write ``trajs`` as the local Minari dataset ``dataset_id`` and return it.

    The dataset goes where Minari puts local datasets (``MINARI_DATASETS_PATH``
    or ``~/.minari/datasets``).

    Args:
        trajs: the dataset; must have actions (see the module docstring).
        dataset_id: Minari id, ``[namespace/]name-v<version>``.
        env: optional Gymnasium env / id / EnvSpec recorded with the dataset
            (its spaces are used unless given).
        observation_space: default ``Box(-inf, inf, (obs_dim,), obs dtype)``.
        action_space: default ``Box(-inf, inf, (act_dim,), action dtype)``.
        algorithm_name: default ``info["source"]`` or ``"loco_il"``.
        author, author_email, code_permalink: Minari metadata, optional.
        description: default names the task and dataset type.
        overwrite: delete an existing local dataset of that id first;
            otherwise an existing id raises :class:`DatasetError`.

    Returns:
        ``minari.MinariDataset``.
    """
    minari = _import_minari()
    import gymnasium as gym
    from minari.data_collector import EpisodeBuffer

    trajs.validate()
    if trajs.actions is None:
        raise DatasetError(
            "Minari datasets require actions, but this dataset has none "
            f"(dataset_type={trajs.dataset_type!r}, states only); save it with Trajectories.save() instead"
        )
    bits = np.dtype(f"u{trajs.obs.dtype.itemsize}")
    same = (trajs.next_obs[:-1].view(bits) == trajs.obs[1:].view(bits)).all(axis=1)
    broken = np.flatnonzero(~same & ~trajs.last[:-1])
    if broken.size:
        raise DatasetError(
            "Minari stores T+1 observations per episode, which needs next_obs[t] == obs[t+1] inside every "
            f"episode; this dataset breaks it at transition(s) {broken[:10].tolist()}"
        )

    if dataset_id in minari.list_local_datasets():
        if not overwrite:
            raise DatasetError(f"a local Minari dataset {dataset_id!r} already exists; pass overwrite=True to replace it")
        minari.delete_dataset(dataset_id)

    if env is None:
        env = _loco_env_spec(trajs.info.get("task_id"))
        if observation_space is None:
            observation_space = gym.spaces.Box(-np.inf, np.inf, (trajs.obs_dim,), dtype=trajs.obs.dtype)
        if action_space is None:
            action_space = gym.spaces.Box(-np.inf, np.inf, (trajs.act_dim,), dtype=trajs.actions.dtype)

    truncations = trajs.last & ~trajs.absorbing
    buffers = []
    for k, (a, b) in enumerate(trajs.episode_bounds()):
        buffers.append(
            EpisodeBuffer(
                id=k,
                observations=np.concatenate([trajs.obs[a:b], trajs.next_obs[b - 1 : b]]),
                actions=trajs.actions[a:b],
                rewards=trajs.rewards[a:b],
                terminations=trajs.absorbing[a:b],
                truncations=truncations[a:b],
            )
        )

    info = trajs.info
    if description is None:
        description = (
            f"loco_il {info.get('dataset_type') or ''} dataset for task {info.get('task_id')!r}: "
            f"{trajs.n_trajectories} episodes, {trajs.n_transitions} transitions"
        )
    with warnings.catch_warnings():
        # Minari warns about every piece of optional metadata left out.
        warnings.filterwarnings("ignore", category=UserWarning, module=r"minari(\.|$)")
        dataset = minari.create_dataset_from_buffers(
            dataset_id=dataset_id,
            buffer=buffers,
            env=env,
            algorithm_name=algorithm_name or info.get("source") or "loco_il",
            author=author,
            author_email=author_email,
            code_permalink=code_permalink,
            action_space=action_space,
            observation_space=observation_space,
            description=description,
        )
    dataset.storage.update_metadata({INFO_METADATA_KEY: _info_to_json(info)})
    return dataset


def _loco_env_spec(task_id: Any) -> Any:
    """The Gymnasium spec of ``gym.make("LocoMujoco", env_name=task_id)``, so that Minari's
    ``recover_environment()`` rebuilds the env; None when ``task_id`` is no Task-ID of ours."""
    import dataclasses

    import gymnasium as gym

    from loco_il.environments.gym_adapter import register_gymnasium
    from loco_il.environments.registry import parse_task_id
    if not isinstance(task_id, str) or not task_id:
        return None
    try:
        parse_task_id(task_id)
    except Exception:      # a dataset from elsewhere: record no env
        return None
    register_gymnasium()
    return dataclasses.replace(gym.spec("LocoMujoco"), kwargs={"env_name": task_id})


def from_minari(dataset_or_id: Any, *, info: Optional[Mapping[str, Any]] = None) -> Trajectories:
    """Read a Minari dataset (object or local id) as :class:`Trajectories`.

    Observations and actions must be flat ``Box`` spaces. Float32/float64
    arrays keep their dtype; other numeric dtypes become float64.

    Args:
        dataset_or_id: a ``minari.MinariDataset`` or the id of a local dataset.
        info: entries that override the restored/built info.
    """
    minari = _import_minari()
    import gymnasium as gym

    if isinstance(dataset_or_id, str):
        try:
            dataset = minari.load_dataset(dataset_or_id)
        except FileNotFoundError as exc:
            raise DatasetError(f"no local Minari dataset {dataset_or_id!r}: {exc}") from exc
    else:
        dataset = dataset_or_id
    for name, space in (("observation", dataset.observation_space), ("action", dataset.action_space)):
        if not isinstance(space, gym.spaces.Box) or len(space.shape) != 1:
            raise DatasetError(f"only flat Box {name} spaces can be converted, got {space}")

    obs, next_obs, actions, rewards, absorbing, last = [], [], [], [], [], []
    for ep in dataset.iterate_episodes():
        o = np.asarray(ep.observations)
        t = len(ep.rewards)
        if t == 0:
            continue
        if o.shape[0] != t + 1:
            raise DatasetError(f"Minari episode {ep.id} has {o.shape[0]} observations for {t} steps (expected {t + 1})")
        obs.append(o[:-1])
        next_obs.append(o[1:])
        actions.append(np.asarray(ep.actions).reshape(t, -1))
        rewards.append(np.asarray(ep.rewards).reshape(t))
        term = np.asarray(ep.terminations, dtype=bool).reshape(t)
        trunc = np.asarray(ep.truncations, dtype=bool).reshape(t)
        end = term | trunc
        end[-1] = True
        absorbing.append(term)
        last.append(end)
    if not obs:
        raise DatasetError(f"Minari dataset {dataset.spec.dataset_id!r} holds no steps")

    def floats(parts):
        arr = np.concatenate(parts)
        return arr if arr.dtype in (np.float32, np.float64) else arr.astype(np.float64)

    metadata = dataset.storage.metadata
    raw = metadata.get(INFO_METADATA_KEY)
    if raw is not None:
        full_info = json.loads(raw)
    else:
        full_info = {
            "task_id": None,
            "dataset_type": None,
            "source": f"minari:{metadata.get('dataset_id')}",
            "obs_names": None,
            "simulator": None,
            "seed": None,
            "policy_checksum": None,
            "minari_version": metadata.get("minari_version"),
        }
    if info:
        full_info.update(info)
    return Trajectories(
        obs=floats(obs),
        next_obs=floats(next_obs),
        actions=floats(actions),
        rewards=floats(rewards),
        absorbing=np.concatenate(absorbing),
        last=np.concatenate(last),
        info=full_info,
    )


__all__ = ["to_minari", "from_minari", "INFO_METADATA_KEY"]
