"""SAC for training experts on the tasks where PPO is too sample-hungry for our budgets (HalfCheetah, Ant, Humanoid).

The learner is the project's shared SAC core (`loco_il.rl.sac.SACCore`: twin critic, target
critic, tanh-squashed Gaussian actor, learned temperature), trained here on the environment's reward with
the soft Bellman target of Haarnoja et al. 2018 ("Soft Actor-Critic Algorithms and Applications",
arXiv:1812.05905):

    y = r + gamma * (1 - absorbing) * (min_i Q_target_i(s', a') - alpha log pi(a'|s')),  a' ~ pi(.|s')
    L_Q = mean (Q_1(s, a) - y)^2 + mean (Q_2(s, a) - y)^2

`absorbing` is set only on termination (a fall), never on a time-limit truncation, whose next state is
bootstrapped. The first `random_steps` env steps take uniform random actions; updates start when the
replay memory holds `learning_starts` transitions and then run `updates_per_step` gradient steps per env
step (summed over the envs). Defaults: `configs/algo/sac.yaml` (with sources).

The shipped expert is the deterministic tanh(mean) policy with no observation normalization
(`ExpertPolicy(..., squash=True)`); the loop, checkpoints (including the replay memory when
`checkpoint_replay`), evaluations, snapshots and files come from `trainer.ExpertTrainer`. A checkpoint
without the replay memory resumes with an empty one, refilled (`learning_starts` steps) before updates go
on: by the current policy, or with `refill_from=<folder>` by the policy files there (e.g. the run's
`snapshots/`), in the order of their step, each sampling an equal share of the steps: closer to the lost
memory, which held the run's whole history, falls included. Neither is the lost memory: a Humanoid run at
650k steps (eval 4781) fell to ~400 within 50k steps after a 10k-step refill by its current policy, and to
~1000 after a 150k-step refill by either source (benchmarks/RESULTS.md, "Experts", "Resuming without the replay memory").

`alive_bonus` shapes the training reward only (the logged returns, evaluations and datasets keep the env's
reward). It matters for tasks whose reward is small and bounded, like the robots' velocity tracking
exp(-(v_x - v*)^2) in (0, 1]: SAC's soft reward r - alpha log pi turns negative once alpha |log pi| exceeds
r, and since a fall ends the episode with no further entropy terms, the policy then learns to fall early
(seen on G1.walk: the critic loss grew to ~5e4 within 90k steps while episodes stayed ~40 steps long).
A fixed bonus only moves the threshold: on G1 the temperature then rose to ~0.45 (noise topples it, so the
policy keeps its entropy below the target) and the same happened at 90k steps. `backup_entropy=false` removes
the cause: the critic's target leaves out the entropy term (Q sums the training reward only, so a fall always
costs), while the actor's loss and the temperature keep theirs.
`value_bounds=[lo, hi]` clips the bootstrapped value V(s') to what the training reward allows (without entropy
terms, rewards in [r_lo, r_hi] give returns in [min(0, r_lo), max(0, r_hi)] / (1 - gamma)), as LS-IQ clips its
targets: on G1 the
critic, fed joint velocities up to ~150, extrapolated to Q ~ 2300 where 300 is the most a return can be.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import torch

from loco_il.rl.networks import GaussianPolicy
from loco_il.rl.replay import TransitionBuffer
from loco_il.rl.sac import SACCore
from loco_il.experts.policy import ACTIVATIONS, ExpertPolicy, load_expert
from loco_il.experts.trainer import CommonConfig, ExpertTrainer


@dataclass
class SACConfig(CommonConfig):
    """Everything `python -m loco_il.experts train algo=sac` accepts (see configs/algo/sac.yaml)."""

    algo: str = "sac"
    num_envs: int = 1
    hidden: Sequence[int] = (256, 256)
    activation: str = "relu"
    eval_interval: int = 50_000
    batch_size: int = 256
    actor_lr: float = 3e-4
    critic_lr: float = 3e-4
    alpha_lr: float = 3e-4
    tau: float = 0.005
    init_alpha: float = 1.0
    target_entropy: float | None = None    # None: -dim(A)
    replay_capacity: int = 1_000_000
    random_steps: int = 10_000
    learning_starts: int = 10_000
    updates_per_step: float = 1.0
    checkpoint_replay: bool = True
    refill_from: str = ""                  # folder of policy files that refill a lost replay memory (see below)
    init_action: str = "zero"              # "home": the initial policy's mean commands the standing keyframe
    init_log_std: float | None = None      # initial log-std of the actor (before tanh); None: default init
    alive_bonus: float = 0.0               # added to every training reward (not to logged returns), see below
    backup_entropy: bool = True            # False: the critic's target leaves out -alpha log pi (see below)
    value_bounds: Sequence[float] | None = None   # [lo, hi]: clip the bootstrapped next-state value (see below)


def soft_td_target(rewards: torch.Tensor, absorbing: torch.Tensor, next_v: torch.Tensor,
                   gamma: float) -> torch.Tensor:
    """y = r + gamma (1 - absorbing) V_target(s')."""
    return rewards + gamma * (1.0 - absorbing) * next_v


def twin_critic_loss(q1: torch.Tensor, q2: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Both heads regress onto the same target (Haarnoja et al. 2018b, Eq. 5, one term per head)."""
    return (q1 - target).pow(2).mean() + (q2 - target).pow(2).mean()


def refill_policies(folder: str) -> list[ExpertPolicy]:
    """The policy files (*.pt) of `folder` in the order of their names (step_XXXXXXXXX.pt: training step)."""
    if not folder:
        return []
    files = sorted(Path(folder).glob("*.pt"))
    if not files:
        raise FileNotFoundError(f"refill_from={folder}: no policy files (*.pt) there")
    return [load_expert(f) for f in files]


def init_actor_output(policy: GaussianPolicy, mean_action: np.ndarray, log_std: float | None) -> None:
    """Start a tanh-squashed actor near `mean_action` (and, unless `log_std` is None, std exp(log_std) before tanh).

    The last layer's rows of each half set here are scaled down (x0.01) so that their biases decide the initial
    output for every observation: bias = atanh(mean_action) for the mean half, `log_std` for the log-std half.
    """
    last = [m for m in policy.net.modules() if isinstance(m, torch.nn.Linear)][-1]
    act = np.clip(np.asarray(mean_action, dtype=np.float64), -0.97, 0.97)   # atanh stays finite
    n = policy.act_dim
    with torch.no_grad():
        last.weight[:n].mul_(0.01)
        last.bias[:n] = torch.as_tensor(np.arctanh(act), dtype=last.bias.dtype)
        if log_std is not None:
            last.weight[n:].mul_(0.01)
            last.bias[n:] = float(log_std)


class SACTrainer(ExpertTrainer):
    config_class = SACConfig
    name = "SAC"

    # ------------------------------------------------------------------ learner
    def build(self) -> None:
        cfg = self.cfg
        self.policy = GaussianPolicy(self.obs_dim, self.act_dim, cfg.hidden, squash=True,
                                     activation=ACTIVATIONS[cfg.activation]).to(self.device)
        if cfg.value_bounds is not None and not (len(cfg.value_bounds) == 2 and cfg.value_bounds[0] < cfg.value_bounds[1]):
            raise ValueError(f"value_bounds={list(cfg.value_bounds)}: expected [lo, hi] with lo < hi")
        if cfg.init_action != "zero" or cfg.init_log_std is not None:
            init_actor_output(self.policy, self.initial_mean(), cfg.init_log_std)
        self.sac = SACCore(self.policy, self.obs_dim, self.act_dim, cfg.hidden, cfg.gamma, cfg.tau,
                           cfg.actor_lr, cfg.critic_lr, cfg.alpha_lr, cfg.init_alpha, True, cfg.target_entropy,
                           None, self.device)
        self.replay = TransitionBuffer(cfg.replay_capacity, self.obs_dim, self.act_dim, self.device,
                                       with_rewards=True)
        self.rng = np.random.default_rng(cfg.seed)
        self._refill_policies: list[ExpertPolicy] = []
        self.n_updates = 0
        self._update_credit = 0.0
        self._stats: dict[str, torch.Tensor] = {}

    def initial_mean(self) -> np.ndarray:
        """The initial policy's mean action: zeros, or the body's home action with `init_action=home`."""
        if self.cfg.init_action == "zero":
            return np.zeros(self.act_dim)
        if self.cfg.init_action != "home":
            raise ValueError(f"init_action={self.cfg.init_action!r}: expected 'zero' or 'home'")
        if "home_action" not in self.body_extra:
            raise ValueError(f"init_action=home: {self.task_id} has no home action (only position-servo robots do)")
        return np.asarray(self.body_extra["home_action"], dtype=np.float64)

    def learner_state(self) -> dict[str, Any]:
        return {"policy": {k: v.detach().cpu() for k, v in self.policy.state_dict().items()},
                "sac": self.sac.state_dict(), "n_updates": self.n_updates,
                "update_credit": self._update_credit, "rng": self.rng.bit_generator.state,
                "replay": self.replay.state_dict() if self.cfg.checkpoint_replay else None}

    def load_learner_state(self, state: Mapping[str, Any]) -> None:
        self.policy.load_state_dict(state["policy"])
        self.sac.load_state_dict(state["sac"])
        self.n_updates = int(state["n_updates"])
        self._update_credit = float(state["update_credit"])
        self.rng.bit_generator.state = state["rng"]
        if state.get("replay") is not None:
            self.replay.load_state_dict(state["replay"])
        else:
            self._refill_policies = refill_policies(self.cfg.refill_from)
            source = (f"{len(self._refill_policies)} policies of {self.cfg.refill_from}" if self._refill_policies
                      else "the current policy")
            self.log(f"[sac] {self.ckpt_path} has no replay memory: refilling it with {source} "
                     f"({self.cfg.learning_starts} steps) before updates go on")

    def make_expert(self, metadata: Mapping[str, Any] | None = None) -> ExpertPolicy:
        # obs_var = 1 - eps makes the expert's normalization (obs - 0) / sqrt(var + eps) the identity
        expert = ExpertPolicy(self.obs_dim, self.act_dim, self.cfg.hidden, self.cfg.activation,
                              np.zeros(self.obs_dim), np.full(self.obs_dim, 1.0 - 1e-8), obs_clip=0.0,
                              obs_eps=1e-8, metadata=metadata, squash=True)
        expert.policy.load_state_dict({k: v.detach().cpu() for k, v in self.policy.state_dict().items()})
        return expert

    def describe(self) -> str:
        cfg = self.cfg
        return (f"{cfg.num_envs} env(s), batch {cfg.batch_size}, {cfg.updates_per_step:g} updates per env step, "
                f"update on {self.device}")

    # ------------------------------------------------------------------ acting and learning
    def start(self) -> None:
        self.reset_envs(salt=self.step)

    @torch.no_grad()
    def _actions(self) -> np.ndarray:
        if self.step < self.cfg.random_steps:
            return self.rng.uniform(-1.0, 1.0, size=(self.cfg.num_envs, self.act_dim)).astype(np.float32)
        if self._refill_policies and len(self.replay) < self.cfg.learning_starts:
            share = len(self.replay) * len(self._refill_policies) // self.cfg.learning_starts
            return self._refill_policies[share].act(self._obs, deterministic=False, rng=self.rng).astype(np.float32)
        obs = torch.as_tensor(self._obs, dtype=torch.float32, device=self.device)
        return self.policy.sample(obs)[0].cpu().numpy()

    def iterate(self) -> Mapping[str, Any]:
        """About 1000 env steps (over all envs), each followed by its share of gradient steps."""
        cfg = self.cfg
        n = cfg.num_envs
        for _ in range(max(1, 1000 // n)):
            if self.step >= cfg.total_steps:
                break
            actions = self._actions()
            next_obs, reward, terminated, truncated, infos = self.envs.step(actions)
            ended = np.asarray(terminated) | np.asarray(truncated)
            real_next = np.array(next_obs, dtype=np.float32, copy=True)
            for i in np.flatnonzero(ended):   # SAME_STEP autoreset: the episode's last obs is in final_obs
                real_next[i] = infos["final_obs"][i]
            self.replay.add(self._obs, real_next, np.asarray(terminated, dtype=np.float32), actions,
                            np.asarray(reward, dtype=np.float32) + np.float32(cfg.alive_bonus))
            self.track_episodes(reward, ended)
            self._obs = next_obs
            self.step += n
            if len(self.replay) >= cfg.learning_starts:
                self._update_credit += n * cfg.updates_per_step
                while self._update_credit >= 1.0:
                    self.update()
                    self._update_credit -= 1.0
        return self._stats

    def update(self) -> dict[str, torch.Tensor]:
        """One critic, actor, temperature and target step on a replay batch."""
        batch = self.replay.sample(self.cfg.batch_size, self.rng)
        next_v = self.sac.target_soft_value(batch["next_obs"], with_entropy=self.cfg.backup_entropy)
        if self.cfg.value_bounds is not None:
            next_v = next_v.clamp(*self.cfg.value_bounds)
        target = soft_td_target(batch["rewards"], batch["absorbing"], next_v, self.sac.gamma)
        q1, q2 = self.sac.critic(batch["obs"], batch["actions"])
        loss = twin_critic_loss(q1, q2, target)
        self.sac.critic_step(loss)
        info = self.sac.actor_step(batch["obs"])
        self.sac.update_target()
        self.n_updates += 1
        info["critic_loss"] = loss.detach()
        self._stats = info
        return info

    def progress_suffix(self, stats: Mapping[str, Any]) -> str:
        s = {k: float(v) for k, v in stats.items()}   # one device sync per progress line, not per update
        return (f"updates {self.n_updates} | q_loss {s.get('critic_loss', 0):.3f} "
                f"alpha {s.get('alpha', 0):.4f} entropy {s.get('entropy', 0):.2f}")
