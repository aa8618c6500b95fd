"""Network building blocks shared by every algorithm.

Kept deliberately small: an MLP builder, a diagonal Gaussian policy (optionally
tanh-squashed, as SAC needs) and a fused twin Q critic. Algorithms compose these;
none of them defines its own copy.
"""
from __future__ import annotations

import math
from typing import Sequence

import torch
from torch import nn

LOG_STD_MIN, LOG_STD_MAX = -20.0, 2.0


def mlp(in_dim: int, out_dim: int, hidden: Sequence[int] = (256, 256),
        activation: type[nn.Module] = nn.ReLU, out_gain: float | None = None) -> nn.Sequential:
    """A plain feed-forward network; `out_gain` scales the last layer's init (small for policies)."""
    layers: list[nn.Module] = []
    last = in_dim
    for width in hidden:
        layers += [nn.Linear(last, width), activation()]
        last = width
    out = nn.Linear(last, out_dim)
    if out_gain is not None:
        nn.init.orthogonal_(out.weight, gain=out_gain)
        nn.init.zeros_(out.bias)
    layers.append(out)
    return nn.Sequential(*layers)


class GaussianPolicy(nn.Module):
    """Diagonal Gaussian policy.

    squash=True gives SAC's tanh-squashed policy with a state-dependent std;
    squash=False gives the PPO/TRPO/BC policy with a state-independent log-std.
    Actions live in [-1, 1] (the environments' normalized action space).
    """

    def __init__(self, obs_dim: int, act_dim: int, hidden: Sequence[int] = (256, 256),
                 squash: bool = True, init_log_std: float = 0.0,
                 activation: type[nn.Module] = nn.ReLU):
        super().__init__()
        self.squash = squash
        self.act_dim = act_dim
        if squash:
            self.net = mlp(obs_dim, 2 * act_dim, hidden, activation)
        else:
            self.net = mlp(obs_dim, act_dim, hidden, activation, out_gain=0.01)
            self.log_std = nn.Parameter(torch.full((act_dim,), float(init_log_std)))

    def _mean_log_std(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        out = self.net(obs)
        if self.squash:
            mean, log_std = out.chunk(2, dim=-1)
            return mean, log_std.clamp(LOG_STD_MIN, LOG_STD_MAX)
        return out, self.log_std.expand_as(out)

    def distribution(self, obs: torch.Tensor) -> torch.distributions.Normal:
        mean, log_std = self._mean_log_std(obs)
        return torch.distributions.Normal(mean, log_std.exp(), validate_args=False)  # no per-call checks on the hot path

    def sample(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Reparameterized sample and its log-probability (summed over action dims)."""
        mean, log_std = self._mean_log_std(obs)
        std = log_std.exp()
        noise = torch.randn_like(mean)
        pre = mean + std * noise
        log_prob = (-0.5 * noise.pow(2) - log_std - 0.5 * math.log(2 * math.pi)).sum(-1)
        if not self.squash:
            return pre, log_prob
        action = torch.tanh(pre)
        # change of variables for tanh, in the numerically stable form
        log_prob = log_prob - (2 * (math.log(2) - pre - nn.functional.softplus(-2 * pre))).sum(-1)
        return action, log_prob

    def log_prob(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        """Log-probability of given actions (unsquashed policies only: PPO, TRPO, BC)."""
        if self.squash:
            raise ValueError("log_prob of a tanh-squashed policy is not used by any algorithm here")
        return self.distribution(obs).log_prob(action).sum(-1)

    def deterministic(self, obs: torch.Tensor) -> torch.Tensor:
        mean, _ = self._mean_log_std(obs)
        return torch.tanh(mean) if self.squash else mean


class TwinQ(nn.Module):
    """Two Q-networks evaluated in one call: Q1(s, a), Q2(s, a), each of shape (batch,)."""

    def __init__(self, obs_dim: int, act_dim: int, hidden: Sequence[int] = (256, 256),
                 activation: type[nn.Module] = nn.ReLU):
        super().__init__()
        self.q1 = mlp(obs_dim + act_dim, 1, hidden, activation)
        self.q2 = mlp(obs_dim + act_dim, 1, hidden, activation)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = torch.cat([obs, action], dim=-1)
        return self.q1(x).squeeze(-1), self.q2(x).squeeze(-1)
