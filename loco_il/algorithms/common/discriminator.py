"""Discriminators for adversarial imitation (GAIL, VAIL, GAIfO) and a running normalizer.

Convention used everywhere here: the discriminator outputs a logit `l`, D = sigmoid(l) is the
probability that the input came from the EXPERT (label 1); agent samples get label 0.

* `discriminator_loss`  binary cross-entropy, expert -> 1, agent -> 0
                        (the GAN objective of Goodfellow et al. 2014 as used in GAIL, Ho & Ermon 2016, eq. 17).
* `gail_reward`         r = -log(1 - D) = softplus(l). Ho & Ermon (2016, Alg. 1) give the policy the cost
                        log D_pi(s, a) where D_pi is the probability of the *policy*; with our expert-probability
                        D = 1 - D_pi this cost is log(1 - D), i.e. the reward -log(1 - D). It is always positive
                        (a survival bonus, see Kostrikov et al. 2019, "Discriminator-Actor-Critic", Sec. 4.1),
                        and it is the form LocoMuJoCo's GAIL/VAIL baselines used.
* `vail_kl`, `vail_beta_update`, `vail_loss`: the Variational Discriminator Bottleneck (Peng et al. 2019).
* `gradient_penalty`    optional zero-centred penalty on expert inputs (R1, Mescheder et al. 2018).

`RunningNormalizer` keeps running mean/variance of its inputs. It only changes when `update()` is
called in training mode; `module.eval()` freezes it (evaluation must not shift the statistics).
"""
from __future__ import annotations

from typing import Sequence

import torch
from torch import nn
from torch.nn import functional as F

from loco_il.rl.networks import mlp


# ---------------------------------------------------------------------------- normalizer
class RunningNormalizer(nn.Module):
    """(x - mean) / std with running statistics (Chan et al.'s parallel variance update), clipped.

    Statistics change only through `update(x)`, and only while `self.training` is True, so a model put
    in `eval()` mode (evaluation, deployment) keeps its statistics fixed.
    """

    def __init__(self, dim: int, clip: float = 10.0, eps: float = 1e-8):
        super().__init__()
        self.clip, self.eps = clip, eps
        self.register_buffer("mean", torch.zeros(dim))
        self.register_buffer("var", torch.ones(dim))
        self.register_buffer("count", torch.zeros((), dtype=torch.float64))

    @torch.no_grad()
    def update(self, x: torch.Tensor) -> None:
        if not self.training:
            return
        x = x.reshape(-1, self.mean.shape[0]).to(self.mean)
        n = x.shape[0]
        if n == 0:
            return
        b_mean, b_var = x.mean(0), x.var(0, unbiased=False)
        total = self.count + n
        w = float(n / total)
        delta = b_mean - self.mean
        self.var.copy_(self.var * (1 - w) + b_var * w + delta.pow(2) * w * (1 - w))
        self.mean.add_(delta * w)
        self.count.copy_(total)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return ((x - self.mean) / torch.sqrt(self.var + self.eps)).clamp(-self.clip, self.clip)


# ---------------------------------------------------------------------------- losses
def discriminator_loss(d_expert_logits: torch.Tensor, d_agent_logits: torch.Tensor) -> torch.Tensor:
    """-E_expert[log D] - E_agent[log(1 - D)] with D = sigmoid(logit); each term is a batch mean."""
    expert_term = F.binary_cross_entropy_with_logits(d_expert_logits, torch.ones_like(d_expert_logits))
    agent_term = F.binary_cross_entropy_with_logits(d_agent_logits, torch.zeros_like(d_agent_logits))
    return expert_term + agent_term


def gail_reward(logits: torch.Tensor) -> torch.Tensor:
    """r = -log(1 - sigmoid(logit)) = softplus(logit), computed without overflow."""
    return F.softplus(logits)


def bernoulli_entropy(logits: torch.Tensor) -> torch.Tensor:
    """Entropy of Bernoulli(sigmoid(logit)), per sample (a discriminator regularizer)."""
    p = torch.sigmoid(logits)
    return (1 - p) * logits + F.softplus(-logits)


def gradient_penalty(disc: nn.Module, expert_inputs: torch.Tensor) -> torch.Tensor:
    """E_expert ||grad_x logit(x)||^2 on the (already normalized) expert inputs (R1 penalty)."""
    x = expert_inputs.detach().requires_grad_(True)
    out = disc.logits_from_features(x)
    grad, = torch.autograd.grad(out.sum(), x, create_graph=True)
    return grad.pow(2).sum(-1).mean()


def vail_kl(mu: torch.Tensor, logstd: torch.Tensor) -> torch.Tensor:
    """KL(N(mu, diag(sigma^2)) || N(0, I)) per sample = 0.5 * sum(mu^2 + sigma^2 - 1 - 2 log sigma)."""
    return 0.5 * (mu.pow(2) + torch.exp(2 * logstd) - 1.0 - 2.0 * logstd).sum(-1)


def vail_beta_update(beta: float, kl: float, i_c: float, lr: float) -> float:
    """Dual ascent on the bottleneck constraint E[KL] <= I_c: beta <- max(0, beta + lr * (E[KL] - I_c))."""
    return max(0.0, float(beta) + float(lr) * (float(kl) - float(i_c)))


def vail_loss(d_expert_logits: torch.Tensor, d_agent_logits: torch.Tensor,
              kl_expert: torch.Tensor, kl_agent: torch.Tensor, beta: float, i_c: float
              ) -> tuple[torch.Tensor, torch.Tensor]:
    """Peng et al. (2019), eq. for VAIL: BCE on sampled-z logits + beta * (E_mix[KL] - I_c).

    The KL expectation is over the equal mixture of expert and agent samples. Returns (loss, mean KL).
    """
    mean_kl = 0.5 * (kl_expert.mean() + kl_agent.mean())
    return discriminator_loss(d_expert_logits, d_agent_logits) + beta * (mean_kl - i_c), mean_kl


# ---------------------------------------------------------------------------- networks
class Discriminator(nn.Module):
    """Logit network on a concatenation of (s), (s, a), (s, s') or (s, a, s').

    States (and next states) go through one shared `RunningNormalizer`; actions are already in [-1, 1].
    """

    def __init__(self, obs_dim: int, act_dim: int, use_actions: bool = True, use_next_states: bool = False,
                 hidden: Sequence[int] = (512, 256), activation: type[nn.Module] = nn.Tanh):
        super().__init__()
        self.obs_dim, self.act_dim = obs_dim, act_dim
        self.use_actions, self.use_next_states = bool(use_actions), bool(use_next_states)
        self.in_dim = obs_dim * (2 if use_next_states else 1) + (act_dim if use_actions else 0)
        self.normalizer = RunningNormalizer(obs_dim)
        self._build_head(hidden, activation)

    def _build_head(self, hidden, activation) -> None:
        self.net = mlp(self.in_dim, 1, hidden, activation)

    @property
    def input_kind(self) -> str:
        return "s" + ("a" if self.use_actions else "") + ("s'" if self.use_next_states else "")

    def update_normalizer(self, *obs_batches: torch.Tensor) -> None:
        for obs in obs_batches:
            self.normalizer.update(obs)

    def features(self, obs: torch.Tensor, actions: torch.Tensor | None = None,
                 next_obs: torch.Tensor | None = None) -> torch.Tensor:
        parts = [self.normalizer(obs)]
        if self.use_actions:
            if actions is None:
                raise ValueError("this discriminator takes actions (use_actions=True) but none were given")
            parts.append(actions)
        if self.use_next_states:
            if next_obs is None:
                raise ValueError("this discriminator takes next states but none were given")
            parts.append(self.normalizer(next_obs))
        return torch.cat(parts, dim=-1)

    def logits_from_features(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x).squeeze(-1)

    def forward(self, obs, actions=None, next_obs=None) -> torch.Tensor:
        return self.logits_from_features(self.features(obs, actions, next_obs))


class VariationalDiscriminator(Discriminator):
    """VDB (Peng et al. 2019): encoder x -> N(mu, sigma) over z, linear decoder z -> logit."""

    def __init__(self, obs_dim: int, act_dim: int, use_actions: bool = True, use_next_states: bool = False,
                 hidden: Sequence[int] = (256,), activation: type[nn.Module] = nn.ReLU, z_dim: int = 128):
        self.z_dim = z_dim
        super().__init__(obs_dim, act_dim, use_actions, use_next_states, hidden, activation)

    def _build_head(self, hidden, activation) -> None:
        self.encoder = mlp(self.in_dim, 2 * self.z_dim, hidden, activation)
        self.decoder = nn.Linear(self.z_dim, 1)

    def encode(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        mu, logstd = self.encoder(x).chunk(2, dim=-1)
        return mu, logstd.clamp(-10.0, 5.0)

    def logits_from_features(self, x: torch.Tensor, sample: bool = False) -> torch.Tensor:
        mu, logstd = self.encode(x)
        z = mu + torch.randn_like(mu) * logstd.exp() if sample else mu
        return self.decoder(z).squeeze(-1)

    def sample_logits_and_kl(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Logits from a reparameterized z ~ q(z|x) and the per-sample KL(q(z|x) || N(0, I))."""
        mu, logstd = self.encode(x)
        z = mu + torch.randn_like(mu) * logstd.exp()
        return self.decoder(z).squeeze(-1), vail_kl(mu, logstd)
