"""VAIL: GAIL with a Variational Discriminator Bottleneck (Peng et al. 2019), TRPO policy step.

The discriminator encodes its input x into q(z|x) = N(mu(x), sigma(x)^2) and decodes a sampled z into a
logit. Its loss (Peng et al. 2019, the VAIL objective) is

    BCE(expert -> 1, agent -> 0 on logits of sampled z) + beta * (E_x~mix[KL(q(z|x) || N(0, I))] - I_c)

with the expectation over the equal expert/agent mixture, and after every discriminator step the dual
variable follows  beta <- max(0, beta + alpha_beta * (E[KL] - I_c))  (`vail_beta_update`).
The agent's reward uses the encoder mean (no sampling): r = -log(1 - D(mu(x))).
Everything else (inputs, state-only switch for 'real' data, TRPO) is GAIL's.
"""
from __future__ import annotations

from typing import ClassVar, Sequence

import torch

from loco_il.algorithms.common.discriminator import (VariationalDiscriminator, gradient_penalty, vail_beta_update,
                                                     vail_loss)
from loco_il.algorithms.gail import GAIL


class VAIL(GAIL):
    name: ClassVar[str] = "vail"
    display_name: ClassVar[str] = "VAIL"
    discriminator_class = VariationalDiscriminator

    def __init__(self, mdp_info, policy_module, device: str = "cpu", seed: int | None = None, *,
                 z_dim: int = 128, info_constraint: float = 0.5, beta_lr: float = 1e-5, beta_init: float = 0.0,
                 disc_hidden: Sequence[int] = (256,), disc_entropy_coef: float = 0.0, **kwargs):
        self.z_dim = z_dim
        self.info_constraint, self.beta_lr = info_constraint, beta_lr
        self.beta = float(beta_init)
        super().__init__(mdp_info, policy_module, device, seed, disc_hidden=disc_hidden,
                         disc_entropy_coef=disc_entropy_coef, **kwargs)
        self._register_checkpoint_attr("beta")

    def _make_discriminator(self) -> VariationalDiscriminator:
        return VariationalDiscriminator(self.obs_dim, self.act_dim, use_actions=self.disc_use_actions,
                                        use_next_states=self.use_next_states, hidden=self.disc_hidden,
                                        z_dim=self.z_dim)

    def _disc_loss(self, x_expert: torch.Tensor, x_agent: torch.Tensor) -> tuple[torch.Tensor, dict]:
        d = self.discriminator
        le, kl_e = d.sample_logits_and_kl(x_expert)
        la, kl_a = d.sample_logits_and_kl(x_agent)
        loss, mean_kl = vail_loss(le, la, kl_e, kl_a, self.beta, self.info_constraint)
        if self.grad_penalty_coef:
            loss = loss + self.grad_penalty_coef * gradient_penalty(d, x_expert)
        return loss, {"vail_kl": mean_kl.item(), "disc_acc_expert": (le > 0).float().mean().item(),
                      "disc_acc_agent": (la < 0).float().mean().item()}

    def _after_disc_step(self, info: dict) -> None:
        self.beta = vail_beta_update(self.beta, info["vail_kl"], self.info_constraint, self.beta_lr)
        info["vail_beta"] = self.beta
