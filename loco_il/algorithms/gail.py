"""GAIL: Generative Adversarial Imitation Learning (Ho & Ermon 2016), with a TRPO policy step.

Each `fit` (one on-policy batch of `n_steps_per_fit` transitions from mushroom-rl's Core):
  1. update the policy's observation normalizer with the batch (the only place it changes);
  2. every `train_disc_every`-th fit, train the discriminator D to tell expert from agent samples
     (`discriminator_loss`, Ho & Ermon Alg. 1 step 4);
  3. replace the environment reward by r = -log(1 - D) (`gail_reward`; the env reward is only logged);
  4. one TRPO step with GAE advantages and a value-function fit (Alg. 1 step 5).

Discriminator inputs: (s, a) by default. With `use_actions=None` (the default) the agent switches to
state-only D(s) when the expert data has no actions ('real' datasets); `use_actions=True` with such
data raises. `use_next_states=True` adds s' (GAIfO, see gaifo.py, uses D(s, s')).
"""
from __future__ import annotations

from typing import ClassVar, Sequence

import numpy as np
import torch

from loco_il.algorithms.common.agent_base import ILAgent
from loco_il.algorithms.common.discriminator import (Discriminator, bernoulli_entropy, discriminator_loss,
                                                     gail_reward, gradient_penalty)
from loco_il.algorithms.common.onpolicy import TRPO, ObsNormalizedPolicy


class GAIL(ILAgent):
    name: ClassVar[str] = "gail"
    display_name: ClassVar[str] = "GAIL"
    supported_datasets: ClassVar[frozenset[str]] = frozenset({"perfect", "preference", "real"})
    discriminator_class: ClassVar[type[Discriminator]] = Discriminator

    def __init__(self, mdp_info, policy_module, device: str = "cpu", seed: int | None = None, *,
                 use_actions: bool | None = None, use_next_states: bool = False,
                 disc_hidden: Sequence[int] = (512, 256), disc_lr: float = 3e-4, disc_batch_size: int = 2048,
                 disc_updates_per_fit: int = 1, train_disc_every: int = 3, disc_entropy_coef: float = 1e-3,
                 grad_penalty_coef: float = 0.0,
                 lam: float = 0.97, max_kl: float = 5e-3, cg_iters: int = 25, cg_damping: float = 1e-1,
                 line_search_steps: int = 10, ent_coef: float = 0.0,
                 vf_hidden: Sequence[int] = (512, 256), vf_lr: float = 1e-3, vf_epochs: int = 5,
                 vf_batch_size: int = 256, normalize_obs: bool = True):
        self.obs_dim = int(mdp_info.observation_space.shape[0])
        self.act_dim = int(mdp_info.action_space.shape[0])
        super().__init__(mdp_info, ObsNormalizedPolicy(policy_module, self.obs_dim, normalize_obs),
                         device=device, seed=seed)
        self.use_actions_arg = use_actions
        self.use_next_states = use_next_states
        self.disc_hidden, self.disc_lr = tuple(disc_hidden), disc_lr
        self.disc_batch_size, self.disc_updates_per_fit = disc_batch_size, disc_updates_per_fit
        self.train_disc_every = max(1, int(train_disc_every))
        self.disc_entropy_coef, self.grad_penalty_coef = disc_entropy_coef, grad_penalty_coef

        self.trpo = TRPO(self.policy_module, self.obs_dim, gamma=mdp_info.gamma, lam=lam, max_kl=max_kl,
                         cg_iters=cg_iters, cg_damping=cg_damping, line_search_steps=line_search_steps,
                         ent_coef=ent_coef, vf_hidden=vf_hidden, vf_lr=vf_lr, vf_epochs=vf_epochs,
                         vf_batch_size=vf_batch_size, device=self.device)
        self._register_checkpoint("value_net", self.trpo.value_net)
        self._register_checkpoint("vf_optimizer", self.trpo.vf_optimizer)

        self.disc_use_actions = use_actions is not False  # resolved again in set_expert
        self._build_discriminator()
        self.n_fits = 0
        self._register_checkpoint_attr("n_fits", "disc_use_actions")
        self.last_fit_info: dict = {}
        self._expert_tensors: dict[str, torch.Tensor | None] = {}

    # ------------------------------------------------------------------ discriminator
    def _make_discriminator(self) -> Discriminator:
        return self.discriminator_class(self.obs_dim, self.act_dim, use_actions=self.disc_use_actions,
                                        use_next_states=self.use_next_states, hidden=self.disc_hidden)

    def _build_discriminator(self) -> None:
        self.discriminator = self._make_discriminator().to(self.device)
        self.disc_optimizer = torch.optim.Adam(self.discriminator.parameters(), lr=self.disc_lr)
        self._ckpt_objects["discriminator"] = self.discriminator
        self._ckpt_objects["disc_optimizer"] = self.disc_optimizer

    def set_expert(self, expert) -> None:
        super().set_expert(expert)
        has_actions = getattr(expert, "actions", None) is not None
        if not has_actions and self.use_actions_arg:
            raise ValueError(f"{self.pretty_name()} was built with use_actions=True, but the expert data has no "
                             "actions (a 'real' dataset): use use_actions=False/None (state-only D(s)) or GAIfO")
        wanted = has_actions and self.use_actions_arg is not False
        if wanted != self.disc_use_actions:
            if self.n_fits > 0:
                raise ValueError("cannot change the discriminator's inputs after training started")
            self.disc_use_actions = wanted
            self._build_discriminator()
        t = self.to_tensor
        self._expert_tensors = {
            "obs": t(expert.obs), "next_obs": t(expert.next_obs) if self.use_next_states else None,
            "actions": t(np.clip(expert.actions, -1.0, 1.0)) if self.disc_use_actions else None}

    def load_state_dict(self, state: dict) -> None:
        saved = state.get("attrs", {}).get("disc_use_actions", self.disc_use_actions)
        if saved != self.disc_use_actions:
            self.disc_use_actions = saved
            self._build_discriminator()
        super().load_state_dict(state)

    def _sample_expert(self, n: int) -> tuple:
        e = self._expert_tensors
        idx = torch.as_tensor(self.rng.integers(0, e["obs"].shape[0], size=n), device=self.device)
        return tuple(None if e[k] is None else e[k][idx] for k in ("obs", "actions", "next_obs"))

    def _disc_loss(self, x_expert: torch.Tensor, x_agent: torch.Tensor) -> tuple[torch.Tensor, dict]:
        d = self.discriminator
        le, la = d.logits_from_features(x_expert), d.logits_from_features(x_agent)
        loss = discriminator_loss(le, la)
        if self.disc_entropy_coef:
            loss = loss - self.disc_entropy_coef * bernoulli_entropy(torch.cat([le, la])).mean()
        if self.grad_penalty_coef:
            loss = loss + self.grad_penalty_coef * gradient_penalty(d, x_expert)
        return loss, {"disc_acc_expert": (le > 0).float().mean().item(),
                      "disc_acc_agent": (la < 0).float().mean().item()}

    def _after_disc_step(self, info: dict) -> None:
        """Hook for VAIL's beta update."""

    def fit_discriminator(self, obs, actions, next_obs) -> dict:
        if not self._expert_tensors:
            raise RuntimeError(f"{self.pretty_name()}: call set_expert(...) before training")
        n = obs.shape[0]
        e_obs, _, _ = self._sample_expert(n)
        self.discriminator.update_normalizer(obs, e_obs)
        info: dict = {}
        for _ in range(self.disc_updates_per_fit):
            bs = min(self.disc_batch_size, n)
            ia = torch.as_tensor(self.rng.choice(n, size=bs, replace=False), device=self.device)
            x_agent = self.discriminator.features(obs[ia], actions[ia], next_obs[ia])
            x_expert = self.discriminator.features(*self._sample_expert(bs))
            loss, info = self._disc_loss(x_expert, x_agent)
            self.disc_optimizer.zero_grad(set_to_none=True)
            loss.backward()
            self.disc_optimizer.step()
            info["disc_loss"] = loss.item()
            self._after_disc_step(info)
        return info

    @torch.no_grad()
    def reward(self, obs: torch.Tensor, actions: torch.Tensor, next_obs: torch.Tensor) -> torch.Tensor:
        """The imitation reward -log(1 - D) of agent transitions (actions already clipped to [-1, 1])."""
        return gail_reward(self.discriminator(obs, actions, next_obs))

    # ------------------------------------------------------------------ training
    def fit(self, dataset, **info) -> None:
        batch = self.parse_dataset(dataset)
        obs, next_obs = self.to_tensor(batch["obs"]), self.to_tensor(batch["next_obs"])
        actions = self.to_tensor(batch["actions"])
        disc_actions = actions.clamp(-1.0, 1.0)  # what the environment executed; expert actions lie in [-1, 1]

        self.policy_module.normalizer.update(obs)
        log = {}
        if self.n_fits % self.train_disc_every == 0:
            log.update(self.fit_discriminator(obs, disc_actions, next_obs))
        rewards = self.reward(obs, disc_actions, next_obs).cpu().numpy().astype(np.float64)
        log.update(self.trpo.update(obs, actions, rewards, next_obs, batch["absorbing"], batch["last"],
                                    self.rng))
        log.update(env_reward_mean=float(batch["rewards"].mean()), il_reward_mean=float(rewards.mean()))
        self.last_fit_info = log
        self.n_fits += 1
