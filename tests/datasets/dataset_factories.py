"""Synthetic datasets shared by the dataset tests (not a test module)."""
from __future__ import annotations

import numpy as np

from loco_il.datasets import Trajectories


def make_dataset(lengths=(5, 3, 7), obs_dim=4, act_dim=2, dtype=np.float64, actions=True, seed=0, absorbing_ep=1,
                 action_dtype=None):
    """Episodes recorded like an env rollout: next_obs[t] == obs[t+1] inside an episode."""
    rng = np.random.default_rng(seed)
    parts = {k: [] for k in ("obs", "next_obs", "actions", "rewards", "absorbing", "last")}
    for i, n in enumerate(lengths):
        states = rng.standard_normal((n + 1, obs_dim)).astype(dtype)
        parts["obs"].append(states[:-1])
        parts["next_obs"].append(states[1:])
        parts["actions"].append(rng.uniform(-1, 1, (n, act_dim)).astype(action_dtype or dtype))
        parts["rewards"].append(rng.standard_normal(n))
        flags = np.zeros(n, dtype=bool)
        flags[-1] = True
        parts["last"].append(flags)
        parts["absorbing"].append(flags.copy() if i == absorbing_ep else np.zeros(n, dtype=bool))
    info = {
        "task_id": "Hopper.run.perfect" if actions else "Hopper.run.real",
        "dataset_type": "perfect" if actions else "real",
        "source": "unit-test",
        "obs_names": [f"o{j}" for j in range(obs_dim)],
        "simulator": "mujoco 3.17.0",
        "seed": seed,
        "policy_checksum": "abc123" if actions else None,
        "mean_return": 1.5,
        "nested": {"level": [1, 2]},
    }
    return Trajectories(
        obs=np.concatenate(parts["obs"]),
        next_obs=np.concatenate(parts["next_obs"]),
        actions=np.concatenate(parts["actions"]) if actions else None,
        rewards=np.concatenate(parts["rewards"]),
        absorbing=np.concatenate(parts["absorbing"]),
        last=np.concatenate(parts["last"]),
        info=info,
    )


def assert_same(a: Trajectories, b: Trajectories, check_info: bool = True) -> None:
    """Arrays equal with equal dtypes (None where absent on both), and equal info unless told not to."""
    for name in ("obs", "next_obs", "actions", "rewards", "absorbing", "last"):
        x, y = getattr(a, name), getattr(b, name)
        if x is None or y is None:
            assert x is None and y is None, name
            continue
        assert x.dtype == y.dtype, name
        np.testing.assert_array_equal(x, y, err_msg=name)
    if check_info:
        assert a.info == b.info
