"""`OffPolicyILAgent`: the SAC-based imitation learners' agent (IQ-Learn, LS-IQ, SQIL) around the SAC core.

The IL methods differ only in the critic objective, so `OffPolicyILAgent` asks its subclass for
`critic_loss(expert_batch, policy_batch, pi_obs)` and does everything else (replay, actor, temperature,
target network) with `loco_il.rl.sac.SACCore`; `pi_obs` is the policy's forward at the batch's states, taken
once per update for the critic's V(s) and the actor step (see `_update_step`).
"""
from __future__ import annotations

import contextlib
import copy
from typing import Sequence

import numpy as np
import torch
from torch import nn

from loco_il.rl.networks import GaussianPolicy
from loco_il.rl.replay import TransitionBuffer
from loco_il.rl.sac import (SACCore, actor_loss, bc_regularized_actor_loss, conservative_penalty, polyak_update,
                            temperature_loss)

from .ablations import ABLATION_NAMES, Ablations
from .agent_base import ILAgent
from .cuda_graph import GraphedStep, make_capturable

# rows of [expert; policy] on which `critic_values` evaluates Q(s, a) or V(s), given the number of expert rows
ROWS = {"all": lambda n_e: slice(None), "expert": lambda n_e: slice(None, n_e), "policy": lambda n_e: slice(n_e, None)}


class OffPolicyILAgent(ILAgent):
    """Replay + expert buffer + SAC; subclasses implement `critic_loss(expert, policy)`.

    Each `fit` adds the new transitions to the replay memory and, once it holds
    `initial_replay_size` transitions, does `updates_per_step` updates per new transition.
    An update samples `batch_size` agent and `expert_batch_size` expert transitions, takes one
    critic step on the subclass's loss, one actor (+ temperature) step every `actor_delay`
    updates on the states of both batches, and one Polyak step of the target critic.

    `actor_ema` (e.g. 1e-4): also keep an exponential moving average of the actor's parameters,
    updated after every actor step with that rate; it never acts during training (training is the same
    with or without it), `averaged_actor()` swaps it in for an evaluation.

    `ablations` (an `Ablations`, `common/ablations.py`; all off by default): changes to the method that test why a
    learner leaves the expert, apart from its own options: `freeze_replay` (no new transitions stored),
    `conservative_weight` (CQL's critic penalty, `conservative_penalty`), `actor_bc_alpha` (TD3+BC's actor loss,
    `bc_regularized_actor_loss`; needs the expert's actions) and `critic_layer_norm` (LayerNorm critics).

    `cuda_graph=True` (device cuda only): after three eager updates, each update is replayed from a captured
    CUDA graph (`common/cuda_graph.py`): the same computation in one launch instead of hundreds, for networks
    too small to keep a GPU busy. Needs `actor_delay=1` (the captured step always takes the actor step).
    """

    needs_expert_actions = True

    def __init__(self, mdp_info, policy_module: GaussianPolicy, *, critic_hidden: Sequence[int] = (256, 256),
                 actor_lr: float = 3e-4, critic_lr: float = 3e-4, alpha_lr: float = 3e-4,
                 init_alpha: float = 1.0, learn_alpha: bool = True, target_entropy: float | None = None,
                 tau: float = 0.005, batch_size: int = 256, expert_batch_size: int = 256,
                 replay_capacity: int = 1_000_000, initial_replay_size: int = 1000,
                 random_initial_steps: int = 0, updates_per_step: int = 1, actor_delay: int = 1,
                 critic_grad_clip: float | None = None, actor_on_expert_states: bool = True,
                 n_critics: int = 2, gamma: float | None = None, actor_ema: float | None = None,
                 ablations: Ablations | None = None, cuda_graph: bool = False, device: str = "cpu",
                 seed: int | None = None):
        super().__init__(mdp_info, policy_module, device=device, seed=seed)
        self.ablations = Ablations() if ablations is None else ablations
        if not isinstance(self.ablations, Ablations):
            raise TypeError(f"ablations must be an Ablations, got {type(ablations).__name__} (a config's flat "
                            "keys become one through loco_il.algorithms.common.ablations.split_ablations)")
        if self.ablations.actor_bc_alpha is not None and not self.needs_expert_actions:
            raise ValueError(f"actor_bc_alpha needs the expert's actions, which {type(self).__name__} "
                             "does not use (a state-only learner)")
        self.obs_dim = int(np.prod(mdp_info.observation_space.shape))
        self.act_dim = int(np.prod(mdp_info.action_space.shape))
        # the learner's discount: the task's MDPInfo.gamma unless the config sets one (an algorithm
        # hyper-parameter in IL: the environment's reward, which gamma belongs to, is not trained on)
        self.gamma = float(mdp_info.gamma if gamma is None else gamma)
        if not 0.0 < self.gamma < 1.0:
            raise ValueError(f"gamma must lie in (0, 1), got {self.gamma}")
        self.sac = SACCore(self.policy_module, self.obs_dim, self.act_dim, critic_hidden, self.gamma, tau,
                           actor_lr, critic_lr, alpha_lr, init_alpha, learn_alpha, target_entropy,
                           critic_grad_clip, self.device, n_critics,
                           critic_layer_norm=self.ablations.critic_layer_norm)
        self.batch_size, self.expert_batch_size = int(batch_size), int(expert_batch_size)
        self.initial_replay_size = int(initial_replay_size)
        self.random_initial_steps = int(random_initial_steps)
        self.updates_per_step, self.actor_delay = int(updates_per_step), int(actor_delay)
        self.actor_on_expert_states = actor_on_expert_states
        self.replay = TransitionBuffer(replay_capacity, self.obs_dim, self.act_dim, self.device)
        self.expert_buffer: TransitionBuffer | None = None
        self.n_transitions = 0
        self.n_updates = 0
        self.last_info: dict[str, torch.Tensor] = {}
        self._register_checkpoint("sac", self.sac)
        self._register_checkpoint_attr("n_transitions", "n_updates")
        self.actor_ema = None if actor_ema is None else float(actor_ema)
        self.policy_ema: nn.Module | None = None
        if self.actor_ema is not None:
            if not 0.0 < self.actor_ema <= 1.0:
                raise ValueError(f"actor_ema must lie in (0, 1], got {actor_ema}")
            self.policy_ema = copy.deepcopy(self.policy_module).requires_grad_(False)
            self._ema_pairs = (list(self.policy_ema.parameters()), list(self.policy_module.parameters()))
            self._register_checkpoint("policy_ema", self.policy_ema)
        self.cuda_graph = bool(cuda_graph)
        if self.cuda_graph and self.device.type != "cuda":
            raise ValueError(f"cuda_graph=True needs device=cuda (CUDA graphs), the agent is on {self.device}")
        if self.cuda_graph and self.actor_delay != 1:
            raise ValueError(f"cuda_graph=True needs actor_delay=1 (the captured update always takes the actor "
                             f"step), got actor_delay={self.actor_delay}")
        self._graphed_step = GraphedStep(self._update_step) if self.cuda_graph else None

    @classmethod
    def _saved_init_kwargs(cls, kwargs: dict) -> dict:
        # agent files written while the ablations were separate keyword arguments hold them flat
        flat = {k: kwargs.pop(k) for k in ABLATION_NAMES if k in kwargs}
        if flat:
            kwargs["ablations"] = Ablations(**flat)
        return kwargs

    # ------------------------------------------------------------------ data
    def set_expert(self, expert) -> None:
        super().set_expert(expert)
        actions = expert.actions if self.needs_expert_actions else None
        self.expert_buffer = TransitionBuffer.from_arrays(
            np.asarray(expert.obs), np.asarray(expert.next_obs), np.asarray(expert.absorbing, dtype=np.float32),
            actions, device=self.device)

    def fit(self, dataset, **info) -> None:
        if self.expert_buffer is None:
            raise RuntimeError("call set_expert(...) before fit")
        d = self.parse_dataset(dataset)
        if not self.ablations.freeze_replay:
            self.replay.add(d["obs"], d["next_obs"], d["absorbing"].astype(np.float32), d["actions"])
        elif len(self.replay) < self.initial_replay_size:
            raise RuntimeError(f"freeze_replay with {len(self.replay)} stored transitions (initial_replay_size "
                               f"{self.initial_replay_size}): no update would ever run; it is meant for a fork "
                               "of a run whose checkpoint holds its replay memory")
        self.n_transitions += len(d["obs"])
        if len(self.replay) >= self.initial_replay_size:
            for _ in range(len(d["obs"]) * self.updates_per_step):
                self.update()

    def _act(self, state) -> np.ndarray:
        if not self.deterministic and self.n_transitions < self.random_initial_steps:
            return self.rng.uniform(-1.0, 1.0, size=self.act_dim)
        return super()._act(state)

    # ------------------------------------------------------------------ learning
    def update(self) -> dict[str, torch.Tensor]:
        expert_idx = self.expert_buffer.sample_indices(self.expert_batch_size, self.rng)
        policy_idx = self.replay.sample_indices(self.batch_size, self.rng)
        if self._graphed_step is None:
            info = self._update_step(expert_idx, policy_idx)
        else:
            if self._graphed_step.graph is None:  # warming up or about to capture: Adam must be capturable
                make_capturable(self.optimizers())
            info = self._graphed_step(expert_idx, policy_idx)
        self.n_updates += 1
        self.last_info = info
        return info

    def optimizers(self) -> list[torch.optim.Optimizer]:
        """Every optimizer an update steps (subclasses with networks of their own add theirs)."""
        return [self.sac.actor_opt, self.sac.critic_opt, self.sac.alpha_opt]

    def _update_step(self, expert_idx: torch.Tensor, policy_idx: torch.Tensor) -> dict[str, torch.Tensor]:
        """One update on the expert and replay rows given: critic step, actor (+ temperature) step, Polyak step.
        Free of host synchronisation, so that `cuda_graph=True` can capture it."""
        expert = self.expert_buffer.gather(expert_idx)
        policy = self.replay.gather(policy_idx)
        take_actor_step = self.n_updates % self.actor_delay == 0
        states = pi_states = None
        if take_actor_step:
            # The policy's forward at the actor's states, once, with gradient: when those are all the batch's
            # states, the critic's V(s) terms sample from it (detached) and the actor step after the critic step
            # samples from it again with fresh noise (the policy has not moved in between): one forward saved.
            states = torch.cat([expert["obs"], policy["obs"]]) if self.actor_on_expert_states else policy["obs"]
            pi_states = self.policy_module._mean_log_std(states)
        loss, info = self.critic_loss(expert, policy, pi_states if self.actor_on_expert_states else None)
        ablations = self.ablations
        if ablations.conservative_weight > 0.0:
            penalty = self.conservative_term(policy)
            loss = loss + ablations.conservative_weight * penalty
            info["conservative_penalty"] = penalty.detach()
        self.sac.critic_step(loss)
        info["critic_loss"] = loss.detach()
        if take_actor_step:
            bc_alpha = ablations.actor_bc_alpha
            bc = None if bc_alpha is None else (expert["obs"], expert["actions"], bc_alpha)
            info.update(self.sac.actor_step(states, bc, pi_states))
            if self.policy_ema is not None:
                with torch.no_grad():
                    torch._foreach_lerp_(*self._ema_pairs, self.actor_ema)
        self.sac.update_target()
        return info

    def load_state_dict(self, state: dict) -> None:
        if self.policy_ema is not None and "policy_ema" not in state:
            # the state of a run without the average (e.g. fork_from with actor_ema added): it starts at the actor
            state = dict(state, policy_ema=state["policy"])
        super().load_state_dict(state)
        if self._graphed_step is not None:  # the optimizers' state tensors were replaced: capture again
            self._graphed_step.reset()

    @contextlib.contextmanager
    def averaged_actor(self):
        """Inside the block the agent acts with the moving average of its actor (needs `actor_ema`).

        The average is copied into the live parameters (same storages, so the numpy fast path of `_act`
        stays valid) and the live values are copied back on exit, also after an exception.
        """
        if self.policy_ema is None:
            raise ValueError(f"{self.pretty_name()} keeps no actor average: construct it with actor_ema=<rate>")
        live = {k: v.detach().clone() for k, v in self.policy_module.state_dict().items()}
        self.policy_module.load_state_dict(self.policy_ema.state_dict())
        try:
            yield self
        finally:
            self.policy_module.load_state_dict(live)

    #: a mean Q this many times `q_upper_bound()` marks a diverged critic: a healthy SQIL run overestimates by up to
    #: ~1.4x (Humanoid.run.perfect), a diverging one passed 35x within 20k env steps (HumanoidTorque.walk.perfect)
    DIVERGENCE_FACTOR = 10.0

    def q_upper_bound(self) -> float | None:
        """The largest mean Q(s, a) the method's rewards allow; None where the method does not bound it."""
        return None

    def critic_divergence(self, q_mean: float) -> str | None:
        """One line saying the critic has diverged when `q_mean` (the last update's mean Q) exceeds
        `DIVERGENCE_FACTOR` times `q_upper_bound()`; None otherwise or without a bound."""
        bound = self.q_upper_bound()
        if bound is None or float(q_mean) <= self.DIVERGENCE_FACTOR * bound:   # a NaN Q counts as diverged
            return None
        return (f"the critic diverged: mean Q {float(q_mean):.4g} exceeds {self.DIVERGENCE_FACTOR:g}x the "
                f"{bound:.4g} that {self.pretty_name()}'s rewards allow (gamma {self.gamma:g})")

    def conservative_term(self, policy: dict) -> torch.Tensor:
        """`conservative_penalty` at the agent batch's states: K uniform random actions in [-1, 1] (the squashed
        policy's action box) against the stored action, one critic forward for all of them."""
        obs, act = policy["obs"], policy["actions"]
        n, k = len(obs), self.ablations.conservative_actions
        random_act = torch.rand(k * n, self.act_dim, device=obs.device) * 2.0 - 1.0
        qs = self.sac.critic(obs.repeat(k + 1, 1), torch.cat([random_act, act]))  # (H, (K + 1) N), k-major
        return conservative_penalty(qs[:, :k * n].unflatten(1, (k, n)), qs[:, k * n:],
                                    self.ablations.conservative_hinge)

    def critic_loss(self, expert: dict, policy: dict, pi_obs: tuple[torch.Tensor, torch.Tensor] | None = None
                    ) -> tuple[torch.Tensor, dict]:
        """The method-specific critic objective on one expert and one agent batch.

        pi_obs: the policy's (mean, log_std) at the states [expert; policy], if the update already has them
        (passed on to `critic_values`); None: computed where needed."""
        raise NotImplementedError

    def critic_values(self, expert: dict, policy: dict, need_v: bool = True,
                      online_next: bool = False, v_on: str = "all", q_on: str = "all",
                      pi_obs: tuple[torch.Tensor, torch.Tensor] | None = None) -> dict[str, torch.Tensor]:
        """Everything the implicit-reward losses need, with one policy and one critic forward.

        Returns, for the concatenation [expert; policy] of length N (first `n_expert` are expert), with H the
        number of critic heads (2 for SAC's twin critic):
          q      (H, N)  Q_i(s, a) of every head (with grad); q_on="expert" / "policy": those rows only
          v      (H, N)  V_i(s) = Q_i(s, a~) - alpha log pi(a~|s), a~ ~ pi(.|s)  (grad into Q only); if need_v.
                         v_on="expert" / "policy" computes it on those rows only ((H, n_expert) / (H, N - n_expert)):
                         rows a loss does not read are neither sampled nor run through the critic
          v_next (H, N)  V(s'): from the online heads (with grad) if online_next, else
                         min_i Q_target_i(s', a') - alpha log pi(a'|s') (no grad), repeated for every head
          absorbing (N,)
        pi_obs: the policy's (mean, log_std) at the N states, e.g. with gradient for the actor step that follows
        (used detached here): V(s) then needs the policy's forward at s' only. The actions drawn are the same
        either way (one noise draw for the V rows and s' together, in that order).
        """
        n_e = len(expert["obs"])
        obs = torch.cat([expert["obs"], policy["obs"]])
        act = torch.cat([expert["actions"], policy["actions"]])
        next_obs = torch.cat([expert["next_obs"], policy["next_obs"]])
        n = len(obs)
        alpha = self.sac.alpha
        for arg, value in (("v_on", v_on), ("q_on", q_on)):
            if value not in ROWS:
                raise ValueError(f"critic_values: {arg} must be one of {tuple(ROWS)}, got {value!r}")
        v_obs = obs[ROWS[v_on](n_e)]
        n_v = len(v_obs)
        q_rows = ROWS[q_on](n_e)
        q_obs, q_act = obs[q_rows], act[q_rows]
        n_q = len(q_obs)
        with torch.no_grad():  # sampled actions are constants for the critic loss
            if need_v and pi_obs is not None:
                rows = ROWS[v_on](n_e)
                next_mean, next_log_std = self.policy_module._mean_log_std(next_obs)
                a_pi, logp = self.policy_module.sample_from(torch.cat([pi_obs[0][rows], next_mean]),
                                                           torch.cat([pi_obs[1][rows], next_log_std]))
            else:
                a_pi, logp = self.policy_module.sample(torch.cat([v_obs, next_obs]) if need_v else next_obs)
        crit_obs, crit_act = [q_obs], [q_act]
        if need_v:
            crit_obs.append(v_obs); crit_act.append(a_pi[:n_v])
        if online_next:
            crit_obs.append(next_obs); crit_act.append(a_pi[-n:])
        qs = self.sac.critic(torch.cat(crit_obs), torch.cat(crit_act))  # (H, rows): [Q; V if need_v; next if online_next]
        out = {"q": qs[:, :n_q], "absorbing": torch.cat([expert["absorbing"], policy["absorbing"]]), "n_expert": n_e}
        if need_v:
            out["v"] = qs[:, n_q:n_q + n_v] - alpha * logp[:n_v]
        if online_next:
            out["v_next"] = qs[:, -n:] - alpha * logp[-n:]
        else:
            with torch.no_grad():
                t_min = self.sac.critic_target(next_obs, a_pi[-n:]).amin(0)
                out["v_next"] = (t_min - alpha * logp[-n:]).expand(len(qs), n)
        return out
