"""Behavioral cloning: maximum likelihood of the expert's actions under a Gaussian policy.

loss(theta) = -E_(s,a)~expert [log pi_theta(a | s)]   (Pomerleau 1991; the Gaussian-likelihood form
learns the mean and the state-independent log-std of `GaussianPolicy(squash=False)`).
`pretrain(n_steps)` trains; `fit` (called by mushroom-rl's Core) does nothing, BC is offline.
Observations are normalized with statistics of the expert data, fixed once computed.
"""
from __future__ import annotations

from typing import ClassVar

import numpy as np
import torch

from loco_il.algorithms.common.agent_base import ILAgent
from loco_il.algorithms.common.onpolicy import ObsNormalizedPolicy


def bc_loss(policy, obs: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
    """Mean negative log-likelihood of expert actions."""
    return -policy.log_prob(obs, actions).mean()


class BC(ILAgent):
    name: ClassVar[str] = "bc"
    display_name: ClassVar[str] = "BC"
    supported_datasets: ClassVar[frozenset[str]] = frozenset({"perfect", "preference"})

    def __init__(self, mdp_info, policy_module, device: str = "cpu", seed: int | None = None, *,
                 lr: float = 1e-3, batch_size: int = 256, weight_decay: float = 0.0, normalize_obs: bool = True):
        obs_dim = int(mdp_info.observation_space.shape[0])
        super().__init__(mdp_info, ObsNormalizedPolicy(policy_module, obs_dim, normalize_obs),
                         device=device, seed=seed)
        self.batch_size = batch_size
        self.optimizer = torch.optim.Adam(self.policy_module.parameters(), lr=lr, weight_decay=weight_decay)
        self._register_checkpoint("optimizer", self.optimizer)
        self.n_updates = 0
        self._register_checkpoint_attr("n_updates")
        self._expert_obs = self._expert_actions = None

    def set_expert(self, expert) -> None:
        super().set_expert(expert)  # raises when the data has no actions
        self._expert_obs = self.to_tensor(expert.obs)
        self._expert_actions = self.to_tensor(np.clip(expert.actions, -1.0, 1.0))
        normalizer = self.policy_module.normalizer
        if normalizer.count.item() == 0:  # computed once; a resumed agent keeps its statistics
            normalizer.update(self._expert_obs)

    def pretrain(self, n_steps: int) -> float:
        """`n_steps` Adam steps on minibatches of expert (s, a); returns the last loss."""
        if self._expert_obs is None:
            raise RuntimeError("BC: call set_expert(...) before pretrain")
        n, loss = self._expert_obs.shape[0], torch.zeros(())
        for _ in range(int(n_steps)):
            idx = torch.as_tensor(self.rng.integers(0, n, size=min(self.batch_size, n)), device=self.device)
            loss = bc_loss(self.policy_module, self._expert_obs[idx], self._expert_actions[idx])
            self.optimizer.zero_grad(set_to_none=True)
            loss.backward()
            self.optimizer.step()
            self.n_updates += 1
        return float(loss.item())

    def fit(self, dataset, **info) -> None:
        """BC does not learn from its own rollouts."""
