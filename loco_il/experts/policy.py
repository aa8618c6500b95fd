"""The shippable expert: observation-normalizer statistics + a `GaussianPolicy`'s weights.

File format (`.pt`, loadable with `torch.load(path, weights_only=True)`; plain tensors, dicts,
lists, strings and numbers only, no pickled classes):

    {"format": "loco_il.expert/v1",
     "metadata": {"task_id", "obs_dim", "act_dim", "hidden", "activation", "obs_clip", "obs_eps",
                  "training_steps", "eval_return", "eval_return_std", "commit", "created", ...},
     "state_dict": {"obs_mean": float64 (obs_dim,), "obs_var": float64 (obs_dim,),
                    "policy.net.0.weight": ..., ..., "policy.log_std": ...}}

`ExpertPolicy.__call__(obs)` is deterministic (the Gaussian's mean, clipped to the action space
[-1, 1]; for a tanh-squashed SAC policy, metadata "squash": true, tanh of the mean); the normalizer
statistics are constants here: using an expert never changes them.
`checksum()` is the sha256 of every tensor of the state dict (names, dtypes, shapes and bytes in
sorted-name order), so two files with the same weights and statistics have the same checksum.
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import time
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import torch
from torch import nn

from loco_il.rl.networks import GaussianPolicy
from loco_il.utils.atomic import atomic_torch_save
from loco_il.utils.plain import to_plain

FORMAT = "loco_il.expert/v1"
ACTIVATIONS: dict[str, type[nn.Module]] = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU}


def normalize_obs(obs: np.ndarray, mean: np.ndarray, var: np.ndarray, clip: float, eps: float) -> np.ndarray:
    """(obs - mean) / sqrt(var + eps), clipped to [-clip, clip], as float32 (the one formula used everywhere)."""
    out = (np.asarray(obs, dtype=np.float64) - mean) / np.sqrt(var + eps)
    if clip > 0:
        out = np.clip(out, -clip, clip)
    return out.astype(np.float32)


def git_commit() -> str:
    """The commit of the loco_il checkout (read-only `git rev-parse`), or "unknown"."""
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).resolve().parent,
                             capture_output=True, text=True, timeout=5)
        return out.stdout.strip() if out.returncode == 0 and out.stdout.strip() else "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


class ExpertPolicy:
    """A trained expert: `action = expert(obs)` for one observation (obs_dim,) or a batch (B, obs_dim)."""

    def __init__(self, obs_dim: int, act_dim: int, hidden: Sequence[int] = (64, 64), activation: str = "tanh",
                 obs_mean: np.ndarray | None = None, obs_var: np.ndarray | None = None,
                 obs_clip: float = 10.0, obs_eps: float = 1e-8, metadata: Mapping[str, Any] | None = None,
                 squash: bool = False):
        if activation not in ACTIVATIONS:
            raise ValueError(f"unknown activation {activation!r}; one of {sorted(ACTIVATIONS)}")
        self.obs_dim, self.act_dim = int(obs_dim), int(act_dim)
        self.hidden = tuple(int(h) for h in hidden)
        self.activation = activation
        self.squash = bool(squash)   # PPO experts: plain Gaussian; SAC experts: tanh-squashed
        self.policy = GaussianPolicy(self.obs_dim, self.act_dim, self.hidden, squash=self.squash,
                                     activation=ACTIVATIONS[activation])
        self.policy.eval()
        self.policy.requires_grad_(False)
        self.obs_mean = np.zeros(self.obs_dim) if obs_mean is None else np.asarray(obs_mean, np.float64).copy()
        self.obs_var = np.ones(self.obs_dim) if obs_var is None else np.asarray(obs_var, np.float64).copy()
        self.obs_clip, self.obs_eps = float(obs_clip), float(obs_eps)
        self.metadata: dict[str, Any] = dict(metadata or {})

    # ------------------------------------------------------------------ acting
    def normalize(self, obs: np.ndarray) -> np.ndarray:
        return normalize_obs(obs, self.obs_mean, self.obs_var, self.obs_clip, self.obs_eps)

    @torch.no_grad()
    def act(self, obs: np.ndarray, deterministic: bool = True, rng: np.random.Generator | None = None,
            noise_scale: float = 1.0) -> np.ndarray:
        """Mean action (deterministic) or a sample mean + noise_scale * std * N(0, 1) drawn with `rng`
        (squashed experts: tanh of the mean, or of mean + noise_scale * std(s) * N(0, 1))."""
        obs = np.asarray(obs)
        if obs.shape[-1] != self.obs_dim:
            raise ValueError(f"expert expects observations of size {self.obs_dim}, got shape {obs.shape}")
        x = torch.from_numpy(self.normalize(obs))
        if self.squash and not deterministic:
            rng = rng if rng is not None else np.random.default_rng()
            pre, log_std = (t.numpy().astype(np.float64) for t in self.policy._mean_log_std(x))
            return np.tanh(pre + noise_scale * np.exp(log_std) * rng.standard_normal(pre.shape))
        mean = self.policy.deterministic(x).numpy().astype(np.float64)
        if not deterministic:
            rng = rng if rng is not None else np.random.default_rng()
            std = self.policy.log_std.exp().numpy().astype(np.float64)
            mean = mean + noise_scale * std * rng.standard_normal(mean.shape)
        return np.clip(mean, -1.0, 1.0)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.act(obs, deterministic=True)

    # ------------------------------------------------------------------ (de)serialization
    def state_dict(self) -> dict[str, torch.Tensor]:
        sd = {"obs_mean": torch.as_tensor(self.obs_mean, dtype=torch.float64).clone(),
              "obs_var": torch.as_tensor(self.obs_var, dtype=torch.float64).clone()}
        sd.update({f"policy.{k}": v.detach().cpu().clone() for k, v in self.policy.state_dict().items()})
        return sd

    def load_state_dict(self, sd: Mapping[str, torch.Tensor]) -> None:
        self.obs_mean = sd["obs_mean"].double().numpy().copy()
        self.obs_var = sd["obs_var"].double().numpy().copy()
        pol = {k[len("policy."):]: v for k, v in sd.items() if k.startswith("policy.")}
        self.policy.load_state_dict(pol)

    def checksum(self) -> str:
        """sha256 over all tensors (name, dtype, shape, bytes) in sorted-name order."""
        h = hashlib.sha256()
        for name, t in sorted(self.state_dict().items()):
            arr = t.contiguous().numpy()
            h.update(name.encode())
            h.update(str(arr.dtype).encode())
            h.update(str(tuple(arr.shape)).encode())
            h.update(arr.tobytes())
        return h.hexdigest()

    def to_file_dict(self) -> dict[str, Any]:
        meta = dict(self.metadata)
        meta.update(obs_dim=self.obs_dim, act_dim=self.act_dim, hidden=list(self.hidden),
                    activation=self.activation, obs_clip=self.obs_clip, obs_eps=self.obs_eps, squash=self.squash)
        return {"format": FORMAT, "metadata": to_plain(meta), "state_dict": self.state_dict()}

    def save(self, path: str | os.PathLike) -> str:
        """Write the expert atomically; returns its checksum."""
        self.metadata.setdefault("commit", git_commit())
        self.metadata.setdefault("created", time.strftime("%Y-%m-%dT%H:%M:%S%z"))
        self.metadata["checksum"] = self.checksum()
        atomic_torch_save(self.to_file_dict(), path)
        return self.metadata["checksum"]

    @classmethod
    def from_file_dict(cls, data: Mapping[str, Any]) -> "ExpertPolicy":
        if not isinstance(data, Mapping) or data.get("format") != FORMAT:
            fmt = data.get("format") if isinstance(data, Mapping) else type(data).__name__
            raise ValueError(f"not a loco_il expert file (format {fmt!r}, expected {FORMAT!r})")
        meta = dict(data["metadata"])
        expert = cls(meta["obs_dim"], meta["act_dim"], meta["hidden"], meta.get("activation", "tanh"),
                     obs_clip=meta.get("obs_clip", 10.0), obs_eps=meta.get("obs_eps", 1e-8), metadata=meta,
                     squash=bool(meta.get("squash", False)))
        expert.load_state_dict(data["state_dict"])
        return expert

    def __repr__(self) -> str:
        return (f"ExpertPolicy(task_id={self.metadata.get('task_id')!r}, obs_dim={self.obs_dim}, "
                f"act_dim={self.act_dim}, hidden={list(self.hidden)}, "
                f"eval_return={self.metadata.get('eval_return')})")


def load_expert(path: str | os.PathLike) -> Any:
    """Load an expert `.pt` written by `ExpertPolicy.save`, or by `TrackingExpert.save` (a policy with its
    reference motion and PD conversion; format "loco_il.tracking_expert/v1"). weights_only: no code is unpickled."""
    data = torch.load(path, map_location="cpu", weights_only=True)
    from loco_il.experts.tracking.expert import FORMAT as TRACKING_FORMAT, TrackingExpert
    if isinstance(data, Mapping) and data.get("format") == TRACKING_FORMAT:
        return TrackingExpert.from_file_dict(data, path)
    expert = ExpertPolicy.from_file_dict(data)
    stored = expert.metadata.get("checksum")
    if stored is not None and stored != expert.checksum():
        raise ValueError(f"{path}: checksum mismatch (file says {stored}, weights hash to {expert.checksum()})")
    return expert
