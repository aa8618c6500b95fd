"""Soft Actor-Critic core shared by the off-policy imitation learners (IQ-Learn, LS-IQ, SQIL) and the SAC expert
trainer (`loco_il.experts.sac`): the losses, the Polyak update and `SACCore` (critics, target, temperature).

SAC as in Haarnoja et al. 2018 ("Soft Actor-Critic Algorithms and Applications", arXiv:1812.05905;
equation numbers below are from memory of that paper and were not re-checked):
  * twin critic Q1, Q2 and a Polyak-averaged target copy                     (Sec. 5, Eq. 5-6)
    (`n_critics=1`: one critic, min_i below is then that critic)
  * actor loss  J_pi = E_s[ alpha log pi(a~|s) - min_i Q_i(s, a~) ],  a~ reparameterized (Eq. 7, 11)
  * temperature J(alpha) = E_a~pi[ -alpha (log pi(a|s) + target_entropy) ], target = -|A|   (Eq. 18)
`loco_il.algorithms.common.sac.OffPolicyILAgent` adds the imitation objectives (the critic loss), the expert
buffer and the ablations.
"""
from __future__ import annotations

import copy
import math
from typing import Sequence

import torch
from torch import nn

from loco_il.rl.networks import EnsembleQ, GaussianPolicy
from loco_il.rl.optim import load_optimizer_state


# ---------------------------------------------------------------------- the three SAC formulas
def actor_loss(alpha: torch.Tensor, log_prob: torch.Tensor, q_min: torch.Tensor) -> torch.Tensor:
    """SAC policy loss (Haarnoja et al. 2018b, Eq. 7): E[alpha log pi(a|s) - min_i Q_i(s, a)]."""
    return (alpha * log_prob - q_min).mean()


def bc_regularized_actor_loss(sac_loss: torch.Tensor, q: torch.Tensor, mean_action: torch.Tensor,
                              expert_action: torch.Tensor, bc_alpha: float) -> torch.Tensor:
    """TD3+BC's actor objective (Fujimoto & Gu 2021, "A Minimalist Approach to Offline Reinforcement Learning",
    arXiv:2106.06860) around SAC's loss: lambda * J_pi + E_E[|pi(s) - a|^2], lambda = bc_alpha / mean |Q|.

    Dividing by the batch's mean |Q| (no gradient) makes bc_alpha independent of the critic's scale (LS-IQ's Q
    reaches 1/(c (1 - gamma)) = 200); the paper's alpha is 2.5. mean_action: the policy's squashed mean at the
    expert states; expert_action: the expert's actions there.
    """
    lam = bc_alpha / q.detach().abs().mean().clamp(min=1e-6)
    return lam * sac_loss + (mean_action - expert_action).pow(2).sum(-1).mean()


def temperature_loss(log_alpha: torch.Tensor, log_prob: torch.Tensor, target_entropy: float) -> torch.Tensor:
    """SAC temperature loss (Eq. 18): E[-alpha (log pi + target_entropy)], alpha = exp(log_alpha).

    Its gradient raises alpha when the policy's entropy -log pi is below the target and lowers it above.
    """
    return -(log_alpha.exp() * (log_prob.detach() + target_entropy)).mean()


def conservative_penalty(q_random: torch.Tensor, q_data: torch.Tensor, hinge: bool = False) -> torch.Tensor:
    """CQL(H)'s critic penalty (Kumar et al. 2020, "Conservative Q-Learning for Offline Reinforcement Learning",
    arXiv:2006.04779): E_s[log mean_k exp Q(s, a_k) - Q(s, a_data)], a_k uniform random actions.

    q_random (H, K, N): each head's Q of K random actions at N states; q_data (H, N): of the stored action.
    Minimizing it lowers the soft maximum of Q over the action space relative to the data's actions. Summed
    over heads. (log mean = logsumexp - log K: the constant changes nothing but makes it 0 when all are equal.)
    hinge=True (our variant): each state's term is clipped at 0 from below, so the penalty only acts where
    random actions look better than the stored one and cannot drive them ever lower (CQL's own term has no
    floor: on Hopper it opened a gap of ~90 within 5k updates, benchmarks/RESULTS.md).
    """
    k = q_random.shape[-2]
    gap = torch.logsumexp(q_random, dim=-2) - math.log(k) - q_data
    return (gap.clamp(min=0.0) if hinge else gap).mean(-1).sum()


@torch.no_grad()
def polyak_update(target: nn.Module, source: nn.Module, tau: float) -> None:
    """target <- (1 - tau) target + tau source, for all parameters at once."""
    t_params, s_params = list(target.parameters()), list(source.parameters())
    torch._foreach_lerp_(t_params, s_params, tau)


class SACCore:
    """Actor, critic (`n_critics` heads, 2: SAC's twin critic), target critic, temperature and their optimizers."""

    def __init__(self, policy: GaussianPolicy, obs_dim: int, act_dim: int,
                 critic_hidden: Sequence[int] = (256, 256), gamma: float = 0.99, tau: float = 0.005,
                 actor_lr: float = 3e-4, critic_lr: float = 3e-4, alpha_lr: float = 3e-4,
                 init_alpha: float = 1.0, learn_alpha: bool = True, target_entropy: float | None = None,
                 critic_grad_clip: float | None = None, device: str | torch.device = "cpu", n_critics: int = 2,
                 critic_layer_norm: bool = False):
        if not getattr(policy, "squash", False):
            raise ValueError("SAC needs a tanh-squashed GaussianPolicy (squash=True)")
        self.device = torch.device(device)
        self.policy = policy
        self.gamma, self.tau = float(gamma), float(tau)
        self.critic = EnsembleQ(obs_dim, act_dim, critic_hidden, n_heads=n_critics,
                                layer_norm=critic_layer_norm).to(self.device)
        self.critic_target = copy.deepcopy(self.critic).requires_grad_(False)
        self.log_alpha = torch.tensor(math.log(init_alpha), device=self.device, requires_grad=True)
        self.learn_alpha = learn_alpha
        self.target_entropy = float(-act_dim if target_entropy is None else target_entropy)
        self.critic_grad_clip = critic_grad_clip
        self._critic_params = list(self.critic.parameters())
        self._target_params = list(self.critic_target.parameters())
        # foreach=True: one fused kernel per optimizer step instead of one per tensor (also on the CPU)
        self.actor_opt = torch.optim.Adam(policy.parameters(), lr=actor_lr, foreach=True)
        self.critic_opt = torch.optim.Adam(self._critic_params, lr=critic_lr, foreach=True)
        self.alpha_opt = torch.optim.Adam([self.log_alpha], lr=alpha_lr, foreach=True)

    @property
    def alpha(self) -> torch.Tensor:
        return self.log_alpha.detach().exp()

    @torch.no_grad()
    def target_soft_value(self, next_obs: torch.Tensor, with_entropy: bool = True) -> torch.Tensor:
        """V_target(s') = min_i Q_target_i(s', a') - alpha log pi(a'|s'), a' ~ pi(.|s').

        with_entropy=False drops the entropy term (the critic then values the reward alone; the actor's
        loss keeps it), for tasks where entropy terms that outweigh the reward would make ending pay.
        """
        a, logp = self.policy.sample(next_obs)
        q = self.critic_target(next_obs, a).amin(0)
        return q - self.alpha * logp if with_entropy else q

    def critic_step(self, loss: torch.Tensor) -> None:
        self.critic_opt.zero_grad(set_to_none=True)
        loss.backward()
        if self.critic_grad_clip is not None:
            nn.utils.clip_grad_norm_(self._critic_params, self.critic_grad_clip)
        self.critic_opt.step()

    def actor_step(self, obs: torch.Tensor, bc: tuple[torch.Tensor, torch.Tensor, float] | None = None,
                   pi_obs: tuple[torch.Tensor, torch.Tensor] | None = None) -> dict[str, torch.Tensor]:
        """One actor step on the states `obs`, then (if learned) one temperature step.

        bc = (expert states, expert actions, alpha): TD3+BC's behaviour-cloning term (`bc_regularized_actor_loss`).
        pi_obs: the policy's (mean, log_std) at `obs`, with gradient, when the caller already ran that forward
        (the same numbers as running it here, since the policy has not moved since).
        """
        for p in self._critic_params:  # gradients only into the policy
            p.requires_grad_(False)
        try:
            a, logp = self.policy.sample(obs) if pi_obs is None else self.policy.sample_from(*pi_obs)
            q = self.critic(obs, a).amin(0)
            loss = actor_loss(self.alpha, logp, q)
            if bc is not None:
                bc_obs, bc_act, bc_alpha = bc
                loss = bc_regularized_actor_loss(loss, q, self.policy.deterministic(bc_obs), bc_act, bc_alpha)
            self.actor_opt.zero_grad(set_to_none=True)
            loss.backward()
            self.actor_opt.step()
        finally:
            for p in self._critic_params:
                p.requires_grad_(True)
        info = {"actor_loss": loss.detach(), "entropy": -logp.detach().mean()}
        if self.learn_alpha:
            a_loss = temperature_loss(self.log_alpha, logp, self.target_entropy)
            self.alpha_opt.zero_grad(set_to_none=True)
            a_loss.backward()
            self.alpha_opt.step()
        info["alpha"] = self.alpha
        return info

    def update_target(self) -> None:
        with torch.no_grad():
            torch._foreach_lerp_(self._target_params, self._critic_params, self.tau)

    def state_dict(self) -> dict:
        return {"critic": self.critic.state_dict(), "critic_target": self.critic_target.state_dict(),
                "log_alpha": self.log_alpha.detach().clone(), "actor_opt": self.actor_opt.state_dict(),
                "critic_opt": self.critic_opt.state_dict(), "alpha_opt": self.alpha_opt.state_dict()}

    def load_state_dict(self, state: dict) -> None:
        self.critic.load_state_dict(state["critic"])
        self.critic_target.load_state_dict(state["critic_target"])
        with torch.no_grad():
            self.log_alpha.copy_(state["log_alpha"])
        for name in ("actor_opt", "critic_opt", "alpha_opt"):
            load_optimizer_state(getattr(self, name), state[name])
