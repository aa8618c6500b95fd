"""SQIL: Soft Q Imitation Learning (Reddy, Dragan, Levine; ICLR 2020, arXiv:1905.11108).

SQIL is plain soft Q-learning / SAC with a constant reward relabelling (the paper's method section and Algorithm 1):
every demonstration transition gets reward 1, every transition of the agent reward 0, and each
update uses equally many samples of both (the paper's lambda_samp = 1 with balanced batches), so
the critic minimizes

    delta^2(D_demo, 1) + delta^2(D_samp, 0),
    delta^2(D, r) = E_D[(Q(s, a) - (r + gamma (1 - absorbing) V_target(s')))^2].

For continuous actions the paper builds SQIL on SAC; here the SAC twin critic with
V_target(s') = min_i Q_target_i(s', a') - alpha log pi(a'|s'), and each head regressed separately.
"""
from __future__ import annotations

import math

import torch

from .common.sac import OffPolicyILAgent


def sqil_rewards(n_expert: int, n_policy: int, device: str | torch.device = "cpu") -> torch.Tensor:
    """SQIL's relabelled rewards for a batch [expert; agent]: 1 for expert, 0 for agent transitions."""
    return torch.cat([torch.ones(n_expert, device=device), torch.zeros(n_policy, device=device)])


def sqil_critic_loss(q: torch.Tensor, rewards: torch.Tensor, v_next: torch.Tensor, absorbing: torch.Tensor,
                     gamma: float) -> tuple[torch.Tensor, dict]:
    """Soft Bellman squared error with the relabelled rewards, mean over samples, summed over heads."""
    target = rewards + gamma * (1.0 - absorbing) * v_next
    loss = (q - target.detach()).pow(2).mean(-1).sum()
    return loss, {"q_mean": q.mean().detach()}


class SQIL(OffPolicyILAgent):
    name = "sqil"
    display_name = "SQIL"
    supported_datasets = frozenset({"perfect", "preference"})

    def critic_loss(self, expert, policy, pi_obs=None):  # pi_obs unused: SQIL's target needs no V(s)
        c = self.critic_values(expert, policy, need_v=False, online_next=False)
        n_e = c["n_expert"]
        rewards = sqil_rewards(n_e, c["q"].shape[-1] - n_e, self.device)
        return sqil_critic_loss(c["q"], rewards, c["v_next"], c["absorbing"], self.gamma)

    def q_upper_bound(self) -> float:
        """(1 + alpha |A| log 2) / (1 - gamma): rewards are at most 1 per step, and the soft term -alpha log pi
        averages at most alpha |A| log 2 (no density on the action box [-1, 1]^|A| has more entropy than the
        uniform one)."""
        return (1.0 + float(self.sac.alpha) * self.act_dim * math.log(2.0)) / (1.0 - self.gamma)
