"""Transition storage for the off-policy agents.

`TransitionBuffer` keeps transitions in preallocated torch tensors on the agent's device, so a
batch is one index gather, with no Python work per sample and no host-to-device copy per
update. It is used both as the agent's ring-buffer replay memory (`add`) and, filled once
with `from_arrays`, as the fixed expert buffer (`actions` may be absent for state-only data).
Rewards are stored only when asked for (`with_rewards=True`): imitation learners never see them,
the SAC expert trainer (`loco_il.experts.sac`) does.
"""
from __future__ import annotations

import numpy as np
import torch

FIELDS = ("obs", "actions", "next_obs", "absorbing", "rewards")


class TransitionBuffer:
    def __init__(self, capacity: int, obs_dim: int, act_dim: int | None, device: str | torch.device = "cpu",
                 with_rewards: bool = False):
        if capacity <= 0:
            raise ValueError("capacity must be positive")
        self.capacity = int(capacity)
        self.device = torch.device(device)
        f32 = dict(dtype=torch.float32, device=self.device)
        self.obs = torch.empty((self.capacity, obs_dim), **f32)
        self.next_obs = torch.empty((self.capacity, obs_dim), **f32)
        self.actions = torch.empty((self.capacity, act_dim), **f32) if act_dim is not None else None
        self.absorbing = torch.empty((self.capacity,), **f32)  # 1.0 where s' is absorbing
        self.rewards = torch.empty((self.capacity,), **f32) if with_rewards else None
        self._pos = 0    # next slot to write
        self._size = 0   # number of valid entries

    # ------------------------------------------------------------------ filling
    @classmethod
    def from_arrays(cls, obs, next_obs, absorbing, actions=None, device="cpu") -> "TransitionBuffer":
        """A full buffer holding exactly the given transitions (e.g. expert demonstrations)."""
        obs = np.asarray(obs)
        buf = cls(len(obs), obs.shape[1], None if actions is None else np.asarray(actions).shape[1], device)
        buf.add(obs, next_obs, absorbing, actions)
        return buf

    def add(self, obs, next_obs, absorbing, actions=None, rewards=None) -> None:
        """Append a batch of transitions (arrays with a leading batch dimension); oldest are overwritten."""
        n = len(obs)
        if (actions is None) != (self.actions is None):
            raise ValueError("actions must be given exactly when the buffer stores actions")
        if (rewards is None) != (self.rewards is None):
            raise ValueError("rewards must be given exactly when the buffer stores rewards (with_rewards=True)")
        if n > self.capacity:  # only the newest `capacity` transitions can survive
            sl = slice(n - self.capacity, n)
            obs, next_obs, absorbing = obs[sl], next_obs[sl], absorbing[sl]
            actions = None if actions is None else actions[sl]
            rewards = None if rewards is None else rewards[sl]
            n = self.capacity
        idx = (self._pos + torch.arange(n)) % self.capacity
        idx = idx.to(self.device)
        as_t = lambda x: torch.as_tensor(np.asarray(x), dtype=torch.float32).to(self.device)  # noqa: E731
        self.obs[idx] = as_t(obs)
        self.next_obs[idx] = as_t(next_obs)
        self.absorbing[idx] = as_t(absorbing).reshape(-1)
        if actions is not None:
            self.actions[idx] = as_t(actions)
        if rewards is not None:
            self.rewards[idx] = as_t(rewards).reshape(-1)
        self._pos = (self._pos + n) % self.capacity
        self._size = min(self._size + n, self.capacity)

    def __len__(self) -> int:
        return self._size

    # ------------------------------------------------------------------ sampling
    def sample(self, batch_size: int, rng: np.random.Generator) -> dict[str, torch.Tensor | None]:
        """Uniform sample with replacement; `rng` is the agent's numpy generator (checkpointed)."""
        return self.gather(self.sample_indices(batch_size, rng))

    def sample_indices(self, batch_size: int, rng: np.random.Generator) -> torch.Tensor:
        """The row indices of `sample`, on the buffer's device (drawn apart from the gather so that a CUDA-graph
        step can take them as its input)."""
        if self._size == 0:
            raise RuntimeError("cannot sample from an empty buffer")
        return torch.as_tensor(rng.integers(0, self._size, size=batch_size)).to(self.device)

    def gather(self, idx: torch.Tensor) -> dict[str, torch.Tensor | None]:
        """The stored transitions at rows `idx`."""
        return {"obs": self.obs[idx], "next_obs": self.next_obs[idx], "absorbing": self.absorbing[idx],
                "actions": None if self.actions is None else self.actions[idx],
                "rewards": None if self.rewards is None else self.rewards[idx]}

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict:
        n = self._size
        return {"capacity": self.capacity, "pos": self._pos, "size": n,
                **{k: None if getattr(self, k) is None else getattr(self, k)[:n].cpu().clone() for k in FIELDS}}

    def load_state_dict(self, state: dict) -> None:
        if state["capacity"] != self.capacity:
            raise ValueError(f"buffer capacity {self.capacity} != checkpoint's {state['capacity']}")
        n = state["size"]
        for k in FIELDS:
            if getattr(self, k) is not None and state.get(k) is not None:
                getattr(self, k)[:n] = state[k].to(self.device)
        self._pos, self._size = state["pos"], n
