"""IQ-Learn: Inverse soft-Q Learning (Garg et al., NeurIPS 2021, arXiv:2106.12142), online, chi^2.

(Section names below are the paper's; equation numbers are deliberately not given because they
were written from memory of the paper and could not be checked against its text here.)

IQ-Learn learns a single soft Q-function whose *implicit reward* is given by the inverse soft
Bellman operator ("Inverse soft Q-learning" section):

    r_Q(s, a) = Q(s, a) - gamma * (1 - absorbing) * V^pi(s'),   V^pi(s) = E_{a~pi}[Q(s, a) - alpha log pi(a|s)].

The critic maximizes the paper's objective

    J(Q) = E_expert[ phi(r_Q(s, a)) ] - (1 - gamma) E_rho0[ V^pi(s0) ]

and, for the chi^2 divergence, phi(x) = x - x^2 / (4 a_chi2) with a_chi2 = 0.5. The initial-state
term has two forms (`value_loss`):
  * "value": replaced, by telescoping, with E_rho[V(s) - gamma V(s')] for rho = the mixture of expert
    and agent samples (the paper's online form; the authors' MuJoCo runs use it for HalfCheetah, Ant);
  * "v0": (1 - gamma) E[V(s0)] with the expert batch's states standing in for initial states (the
    authors' code does this; their MuJoCo runs use it for Hopper, Walker2d, Humanoid). Agent samples
    then enter the critic loss only through the chi^2 penalty, which pulls their implicit reward
    towards 0 instead of below it: on tasks that end when the robot falls, a negative reward on the
    agent's states makes falling early pay (measured on Hopper: benchmarks/RESULTS.md).
Variant implemented here (the paper's online setting):
  * the chi^2 penalty 1/(4 a_chi2) E[r_Q^2] is applied to expert AND agent samples (IQ-Learn's
    online practice of regularizing on both; LS-IQ analyses exactly this mixture regularizer),
  * absorbing states have V(s_A) = 0 (the (1 - absorbing) mask), as in the original method,
  * V(s') is taken from the Polyak target critic by default (`use_target=True`, as in the authors'
    MuJoCo runs); `use_target=False` takes it from the online critic (the objective is then a
    function of one Q, as written in the paper).
  * defaults (`value_loss="v0"`, `use_target=True`) are the authors' Hopper settings; the paper's
    "value" form stays available.
  * one difference from the authors' code: their chi^2 term on agent samples uses Q(s, a~pi(s)),
    ours uses the replay action's Q(s, a), the mixture regularizer that LS-IQ analyses.
The twin critic trains each head on this objective separately (losses summed); the actor is SAC's.
"""
from __future__ import annotations

import torch

from .common.sac import OffPolicyILAgent


VALUE_LOSSES = ("value", "v0")


def iq_critic_loss(q: torch.Tensor, v: torch.Tensor, v_next: torch.Tensor, absorbing: torch.Tensor,
                   n_expert: int, gamma: float, chi2_coef: float = 0.5,
                   regularize_policy: bool = True, value_loss: str = "value") -> tuple[torch.Tensor, dict]:
    """IQ-Learn critic loss -J(Q) (module docstring), summed over any leading (head) dimensions.

    q, v, v_next: (..., N) with the first `n_expert` entries expert samples, the rest agent samples;
    q = Q(s, a), v = V(s), v_next = V(s'); absorbing: (N,) 1 where s' is absorbing.
    chi2_coef = 1 / (4 a_chi2); value_loss: "value" or "v0" (module docstring).
    """
    y_next = gamma * (1.0 - absorbing) * v_next
    r = q - y_next                                       # implicit reward r_Q
    expert_term = -r[..., :n_expert].mean(-1)            # -E_expert[r_Q]
    if value_loss == "value":
        value_term = (v - y_next).mean(-1)               # E_mix[V(s) - gamma V(s')]
    elif value_loss == "v0":
        value_term = (1.0 - gamma) * v[..., :n_expert].mean(-1)  # (1 - gamma) E[V(s0)], s0 ~ expert states
    else:
        raise ValueError(f"value_loss must be one of {VALUE_LOSSES}, got {value_loss!r}")
    r_reg = r if regularize_policy else r[..., :n_expert]
    chi2_term = chi2_coef * r_reg.pow(2).mean(-1)        # 1/(4a) E[r_Q^2]
    loss = (expert_term + value_term + chi2_term).sum()
    info = {"reward_expert": r[..., :n_expert].mean().detach(),
            "reward_policy": r[..., n_expert:].mean().detach()}
    return loss, info


class IQLearn(OffPolicyILAgent):
    name = "iqlearn"
    display_name = "IQ-Learn"
    supported_datasets = frozenset({"perfect", "preference"})

    def __init__(self, mdp_info, policy_module, *, chi2_alpha: float = 0.5, use_target: bool = True,
                 regularize_policy: bool = True, value_loss: str = "v0", **kwargs):
        if value_loss not in VALUE_LOSSES:
            raise ValueError(f"IQLearn: value_loss must be one of {VALUE_LOSSES}, got {value_loss!r}")
        super().__init__(mdp_info, policy_module, **kwargs)
        self.value_loss = value_loss
        self.chi2_coef = 1.0 / (4.0 * chi2_alpha)
        self.use_target = use_target
        self.regularize_policy = regularize_policy

    def critic_loss(self, expert, policy, pi_obs=None):
        c = self.critic_values(expert, policy, need_v=True, online_next=not self.use_target, pi_obs=pi_obs,
                               v_on="expert" if self.value_loss == "v0" else "all")  # "v0" reads V on expert states only
        return iq_critic_loss(c["q"], c["v"], c["v_next"], c["absorbing"], c["n_expert"], self.gamma,
                              self.chi2_coef, self.regularize_policy, self.value_loss)
