"""PPO for training the experts that generate the `perfect` and `preference` datasets.

The algorithm follows Schulman et al. 2017, "Proximal Policy Optimization Algorithms" (clipped surrogate,
eq. 7; generalized advantage estimation, eq. 11-12, from Schulman et al. 2016; epochs of minibatch Adam
updates on a batch of on-policy data), with the implementation choices that Andrychowicz et al. 2021,
"What Matters in On-Policy Reinforcement Learning? A Large-Scale Empirical Study", recommend for MuJoCo:
separate policy and value networks, tanh activations, orthogonal initialization with the policy's last
layer scaled by 0.01, observation normalization, no value-loss clipping, Adam with learning rate 3e-4.

Pieces:
* `RunningMeanStd`  running mean/variance of a stream of batches (parallel variance formula of
                    Chan, Golub & LeVeque 1979). Updated only while collecting training rollouts; frozen
                    (read, never updated) in evaluation and in the shipped expert (`policy.ExpertPolicy`).
* `compute_gae`     GAE(lambda) with separate termination and episode-end flags:
                      delta_t = r_t + gamma * (1 - terminated_t) * V(s'_t) - V(s_t)
                      A_t     = delta_t + gamma * lambda * (1 - ended_t) * A_{t+1}
                    On truncation (time limit) s'_t is the episode's real last observation and V(s'_t) is
                    bootstrapped; on termination it is not. ended_t = terminated_t or truncated_t.
* `PPO`             the learner: networks, Adam optimizers (linearly decayed learning rate), acting, update.
* `PPOTrainer`      vectorized rollouts and optional reward scaling (divide rewards by the running std of
                    the discounted return, "reward scaling" in Engstrom et al. 2020, "Implementation Matters
                    in Deep Policy Gradients"); checkpoint/resume, evaluations, `best.pt`, snapshots and
                    progress lines come from `trainer.ExpertTrainer`.

Defaults (`TrainConfig`; `configs/train.yaml` mirrors them): gamma 0.99, lambda 0.95, clip 0.2, 10 epochs,
Adam 3e-4 (Schulman et al. 2017, Table 3, MuJoCo); 2048-step batches as in that table (16 envs x 128 steps,
2 envs x 1024); larger minibatches (512) than the paper's 64 so that an epoch is 4 Adam steps and the
update keeps up with 16 env processes; tanh [64, 64] networks (Schulman et al. 2017, sec. 6.1);
gradient-norm clipping 0.5, Adam epsilon 1e-5, observation and scaled-reward clipping to +-10 (OpenAI
Baselines' ppo2 / VecNormalize defaults). Measured with these defaults (16 envs, 16-core H100 machine, update
on the GPU): Hopper.run reaches an evaluation return > 3000 after ~0.8M steps and 3263 +- 2 after 2M steps
in 450 s (4.45k env steps/s).
"""
from __future__ import annotations

import collections
import copy
import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
import torch
from torch import nn

from loco_il.rl.networks import GaussianPolicy, mlp
from loco_il.experts.policy import ACTIVATIONS, ExpertPolicy, normalize_obs
from loco_il.experts.trainer import CommonConfig, ExpertTrainer, resolve_device  # noqa: F401 (re-exported)


# ---------------------------------------------------------------------------- configuration
@dataclass
class TrainConfig(CommonConfig):
    """Everything `python -m loco_il.experts train` (algo=ppo) accepts (flat; see configs/train.yaml)."""

    algo: str = "ppo"
    # PPO
    batch_size: int = 2048            # env steps per rollout, split over the envs ...
    num_steps: int | None = None      # ... unless given: steps per env per rollout (batch = num_envs * num_steps)
    epochs: int = 10
    minibatch_size: int = 512
    lr: float = 3e-4
    lr_decay: bool = True             # linear decay to 0 over total_steps
    gae_lambda: float = 0.95
    clip: float = 0.2
    vf_coef: float = 0.5
    ent_coef: float = 0.0
    max_grad_norm: float = 0.5
    target_kl: float | None = None    # stop an update's epochs early when the approximate KL exceeds this
    norm_adv: bool = True
    norm_obs: bool = True
    obs_clip: float = 10.0
    norm_reward: bool = True
    reward_clip: float = 10.0
    init_log_std: float = 0.0

    RESUME_FIXED = ("hidden", "activation", "norm_obs")

    @property
    def steps_per_env(self) -> int:
        return int(self.num_steps) if self.num_steps else max(1, math.ceil(self.batch_size / self.num_envs))



# ---------------------------------------------------------------------------- normalizer, GAE
class RunningMeanStd:
    """Mean and variance of everything passed to `update` (float64)."""

    def __init__(self, shape: tuple[int, ...] = ()):
        self.mean = np.zeros(shape, dtype=np.float64)
        self.var = np.ones(shape, dtype=np.float64)
        self.count = 1e-4

    def update(self, x: np.ndarray) -> None:
        x = np.asarray(x, dtype=np.float64).reshape((-1,) + self.mean.shape)
        b_mean, b_var, b_count = x.mean(axis=0), x.var(axis=0), x.shape[0]
        delta = b_mean - self.mean
        total = self.count + b_count
        self.mean = self.mean + delta * b_count / total
        m2 = self.var * self.count + b_var * b_count + delta ** 2 * self.count * b_count / total
        self.var = m2 / total
        self.count = total

    def state_dict(self) -> dict[str, Any]:
        return {"mean": torch.from_numpy(np.array(self.mean, dtype=np.float64)),
                "var": torch.from_numpy(np.array(self.var, dtype=np.float64)),
                "count": float(self.count)}

    def load_state_dict(self, sd: Mapping[str, Any]) -> None:
        self.mean = sd["mean"].double().numpy().copy()
        self.var = sd["var"].double().numpy().copy()
        self.count = float(sd["count"])


def compute_gae(rewards: np.ndarray, values: np.ndarray, next_values: np.ndarray, terminated: np.ndarray,
                ended: np.ndarray, gamma: float, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """Advantages and value targets (A + V) for arrays of shape (T,) or (T, num_envs), time first.

    `next_values[t]` is V(s'_t), the value of the observation that step t led to (for a truncated
    episode: its real last observation, not the next episode's first). The recursion is cut wherever
    `ended` is set and after the last row; terminated steps do not bootstrap.
    """
    rewards = np.asarray(rewards, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    not_term = 1.0 - np.asarray(terminated, dtype=np.float64)
    cont = 1.0 - np.asarray(ended, dtype=np.float64)
    deltas = rewards + gamma * not_term * np.asarray(next_values, dtype=np.float64) - values
    adv = np.zeros_like(deltas)
    running = np.zeros_like(deltas[0])
    for t in range(deltas.shape[0] - 1, -1, -1):
        running = deltas[t] + gamma * lam * cont[t] * running
        adv[t] = running
    return adv, adv + values


def orthogonal_init(module: nn.Module, gain: float = math.sqrt(2)) -> None:
    """Orthogonal weights (gain sqrt 2) and zero biases for every hidden Linear layer of an `mlp`.

    The last layer is left as `mlp(out_gain=...)` set it (0.01 for the policy mean, 1 for the value).
    """
    linears = [m for m in module.modules() if isinstance(m, nn.Linear)]
    for lin in linears[:-1]:
        nn.init.orthogonal_(lin.weight, gain=gain)
        nn.init.zeros_(lin.bias)




# ---------------------------------------------------------------------------- learner
class PPO:
    """The PPO learner. Acting happens on a CPU copy of the networks; updates on `device`."""

    def __init__(self, obs_dim: int, act_dim: int, cfg: TrainConfig, device: torch.device | str = "cpu"):
        self.cfg, self.obs_dim, self.act_dim = cfg, obs_dim, act_dim
        self.device = torch.device(device)
        act_cls = ACTIVATIONS[cfg.activation]
        self.policy = GaussianPolicy(obs_dim, act_dim, cfg.hidden, squash=False,
                                     init_log_std=cfg.init_log_std, activation=act_cls)
        orthogonal_init(self.policy.net)
        self.value = mlp(obs_dim, 1, cfg.hidden, act_cls, out_gain=1.0)
        orthogonal_init(self.value)
        self.policy.to(self.device)
        self.value.to(self.device)
        self.pi_opt = torch.optim.Adam(self.policy.parameters(), lr=cfg.lr, eps=1e-5, foreach=True)
        self.v_opt = torch.optim.Adam(self.value.parameters(), lr=cfg.lr, eps=1e-5, foreach=True)
        self.obs_rms = RunningMeanStd((obs_dim,))
        self.ret_rms = RunningMeanStd(())
        if self.device.type == "cpu":
            self.actor, self.critic = self.policy, self.value
        else:
            self.actor, self.critic = copy.deepcopy(self.policy).cpu(), copy.deepcopy(self.value).cpu()
        self.updates = 0

    # -- observation normalization (frozen unless `update_obs_stats` is called)
    def normalize(self, obs: np.ndarray) -> np.ndarray:
        if not self.cfg.norm_obs:
            return np.asarray(obs, dtype=np.float32)
        return normalize_obs(obs, self.obs_rms.mean, self.obs_rms.var, self.cfg.obs_clip, 1e-8)

    def update_obs_stats(self, obs: np.ndarray) -> None:
        if self.cfg.norm_obs:
            self.obs_rms.update(obs)

    @torch.no_grad()
    def act(self, nobs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sampled actions, their log-probabilities and V(s) for normalized observations (batched)."""
        x = torch.from_numpy(nobs)
        action, logp = self.actor.sample(x)
        return action.numpy(), logp.numpy(), self.critic(x).squeeze(-1).numpy()

    @torch.no_grad()
    def values(self, nobs: np.ndarray) -> np.ndarray:
        return self.critic(torch.from_numpy(nobs)).squeeze(-1).numpy()

    def set_lr(self, lr: float) -> None:
        for opt in (self.pi_opt, self.v_opt):
            for group in opt.param_groups:
                group["lr"] = lr

    def update(self, batch: Mapping[str, np.ndarray]) -> dict[str, float]:
        """Epochs of minibatch updates on one rollout (flattened arrays: obs, actions, logp, adv, returns)."""
        cfg, dev = self.cfg, self.device
        obs = torch.as_tensor(batch["obs"], device=dev)
        actions = torch.as_tensor(batch["actions"], device=dev)
        old_logp = torch.as_tensor(batch["logp"], device=dev)
        adv_all = torch.as_tensor(batch["adv"], dtype=torch.float32, device=dev)
        returns = torch.as_tensor(batch["returns"], dtype=torch.float32, device=dev)
        n = obs.shape[0]
        mb = max(1, min(cfg.minibatch_size, n))
        stats = collections.defaultdict(list)
        stop = False
        for _ in range(cfg.epochs):
            perm = torch.randperm(n).to(dev)
            for start in range(0, n, mb):
                idx = perm[start:start + mb]
                dist = self.policy.distribution(obs[idx])
                logp = dist.log_prob(actions[idx]).sum(-1)
                entropy = dist.entropy().sum(-1).mean()
                log_ratio = logp - old_logp[idx]
                ratio = log_ratio.exp()
                adv = adv_all[idx]
                if cfg.norm_adv and adv.numel() > 1:
                    adv = (adv - adv.mean()) / (adv.std() + 1e-8)
                pg_loss = -torch.min(ratio * adv, ratio.clamp(1 - cfg.clip, 1 + cfg.clip) * adv).mean()
                v_loss = 0.5 * (self.value(obs[idx]).squeeze(-1) - returns[idx]).pow(2).mean()
                loss = pg_loss - cfg.ent_coef * entropy + cfg.vf_coef * v_loss
                self.pi_opt.zero_grad(set_to_none=True)
                self.v_opt.zero_grad(set_to_none=True)
                loss.backward()
                if cfg.max_grad_norm and cfg.max_grad_norm > 0:
                    nn.utils.clip_grad_norm_(self.policy.parameters(), cfg.max_grad_norm)
                    nn.utils.clip_grad_norm_(self.value.parameters(), cfg.max_grad_norm)
                self.pi_opt.step()
                self.v_opt.step()
                with torch.no_grad():   # k3 estimator of KL(old || new)
                    approx_kl = ((ratio - 1) - log_ratio).mean()
                    clipfrac = ((ratio - 1).abs() > cfg.clip).float().mean()
                stats["pg_loss"].append(pg_loss.detach())
                stats["v_loss"].append(v_loss.detach())
                stats["entropy"].append(entropy.detach())
                stats["approx_kl"].append(approx_kl)
                stats["clipfrac"].append(clipfrac)
                if cfg.target_kl is not None and float(approx_kl) > cfg.target_kl:
                    stop = True
                    break
            if stop:
                break
        self.updates += 1
        self._sync_actor()
        out = {k: float(torch.stack(v).mean()) for k, v in stats.items()}
        out["std"] = float(self.policy.log_std.detach().exp().mean())
        return out

    def _sync_actor(self) -> None:
        if self.actor is not self.policy:
            self.actor.load_state_dict(self.policy.state_dict())
            self.critic.load_state_dict(self.value.state_dict())

    # -- experts and checkpoints
    def make_expert(self, metadata: Mapping[str, Any] | None = None) -> ExpertPolicy:
        cfg = self.cfg
        mean = self.obs_rms.mean if cfg.norm_obs else np.zeros(self.obs_dim)
        var = self.obs_rms.var if cfg.norm_obs else np.full(self.obs_dim, 1.0 - 1e-8)
        expert = ExpertPolicy(self.obs_dim, self.act_dim, cfg.hidden, cfg.activation, mean, var,
                              obs_clip=cfg.obs_clip if cfg.norm_obs else 0.0, obs_eps=1e-8, metadata=metadata)
        expert.policy.load_state_dict({k: v.detach().cpu() for k, v in self.policy.state_dict().items()})
        return expert

    def state_dict(self) -> dict[str, Any]:
        cpu = lambda sd: {k: v.detach().cpu() for k, v in sd.items()}  # noqa: E731
        return {"policy": cpu(self.policy.state_dict()), "value": cpu(self.value.state_dict()),
                "pi_opt": self.pi_opt.state_dict(), "v_opt": self.v_opt.state_dict(),
                "obs_rms": self.obs_rms.state_dict(), "ret_rms": self.ret_rms.state_dict(),
                "updates": self.updates}

    def load_state_dict(self, sd: Mapping[str, Any]) -> None:
        self.policy.load_state_dict(sd["policy"])
        self.value.load_state_dict(sd["value"])
        self.pi_opt.load_state_dict(sd["pi_opt"])
        self.v_opt.load_state_dict(sd["v_opt"])
        self.obs_rms.load_state_dict(sd["obs_rms"])
        self.ret_rms.load_state_dict(sd["ret_rms"])
        self.updates = int(sd["updates"])
        self._sync_actor()


# ---------------------------------------------------------------------------- training loop
class PPOTrainer(ExpertTrainer):
    """PPO expert training (the loop, checkpoints, evaluations and files: `trainer.ExpertTrainer`)."""

    config_class = TrainConfig
    name = "PPO"

    def build(self) -> None:
        self.agent = PPO(self.obs_dim, self.act_dim, self.cfg, self.device)
        self.collect_time = 0.0   # seconds spent in rollouts this session (share of "train" in progress lines)

    def learner_state(self) -> dict[str, Any]:
        return self.agent.state_dict()

    def load_learner_state(self, state: Mapping[str, Any]) -> None:
        self.agent.load_state_dict(state)

    def make_expert(self, metadata: Mapping[str, Any] | None = None) -> ExpertPolicy:
        return self.agent.make_expert(metadata)

    def describe(self) -> str:
        cfg = self.cfg
        return (f"{cfg.num_envs} envs ({'async' if _is_async(cfg) else 'sync'}), "
                f"batch {cfg.num_envs * cfg.steps_per_env}, update on {self.device}")

    def start(self) -> None:
        self.reset_envs(salt=self.iteration)
        self._disc_ret = np.zeros(self.cfg.num_envs)

    def iterate(self) -> dict[str, float]:
        """One rollout and one PPO update (learning rate decayed linearly over the budget)."""
        cfg = self.cfg
        # set every iteration: a resumed run takes this config's rate, not the one stored with the optimizer
        self.agent.set_lr(cfg.lr * (max(0.0, 1.0 - self.step / cfg.total_steps) if cfg.lr_decay else 1.0))
        t0 = time.perf_counter()
        batch = self.collect()
        self.collect_time += time.perf_counter() - t0
        return self.agent.update(batch)

    def progress_suffix(self, stats: Mapping[str, float]) -> str:
        train = self._timers.get("train", 0.0) or 1.0
        return (f"collect {100 * min(1.0, self.collect_time / train):.0f}% of train | "
                f"kl {stats.get('approx_kl', 0):.4f} clip {stats.get('clipfrac', 0):.3f} "
                f"vloss {stats.get('v_loss', 0):.3f} std {stats.get('std', 0):.3f}")

    def collect(self) -> dict[str, np.ndarray]:
        """One rollout of num_steps per env; returns the flattened training batch."""
        cfg, agent = self.cfg, self.agent
        T, N = cfg.steps_per_env, cfg.num_envs
        obs_b = np.zeros((T, N, self.obs_dim), dtype=np.float32)
        act_b = np.zeros((T, N, self.act_dim), dtype=np.float32)
        logp_b, val_b, rew_b = (np.zeros((T, N), dtype=np.float32) for _ in range(3))
        next_val_b = np.zeros((T, N), dtype=np.float32)
        term_b, end_b = np.zeros((T, N), dtype=bool), np.zeros((T, N), dtype=bool)
        for t in range(T):
            agent.update_obs_stats(self._obs)
            nobs = agent.normalize(self._obs)
            action, logp, value = agent.act(nobs)
            next_obs, reward, terminated, truncated, infos = self.envs.step(np.clip(action, -1.0, 1.0))
            reward = np.asarray(reward, dtype=np.float64)
            ended = terminated | truncated
            self.track_episodes(reward, ended)
            if cfg.norm_reward:
                self._disc_ret = self._disc_ret * cfg.gamma + reward
                agent.ret_rms.update(self._disc_ret)
                reward = np.clip(reward / math.sqrt(agent.ret_rms.var + 1e-8), -cfg.reward_clip, cfg.reward_clip)
                self._disc_ret[ended] = 0.0
            bootstrap = truncated & ~terminated
            if bootstrap.any():   # V of the real last observation of time-limited episodes
                idx = np.flatnonzero(bootstrap)
                final = np.stack([infos["final_obs"][i] for i in idx])
                next_val_b[t, idx] = agent.values(agent.normalize(final))
            obs_b[t], act_b[t], logp_b[t], val_b[t], rew_b[t] = nobs, action, logp, value, reward
            term_b[t], end_b[t] = terminated, ended
            self._obs = next_obs
        last_values = agent.values(agent.normalize(self._obs))
        following = np.concatenate([val_b[1:], last_values[None]], axis=0)
        next_val_b = np.where(end_b, next_val_b, following)
        adv, returns = compute_gae(rew_b, val_b, next_val_b, term_b, end_b, cfg.gamma, cfg.gae_lambda)
        self.step += T * N
        flat = lambda a: a.reshape((T * N,) + a.shape[2:])  # noqa: E731
        return {"obs": flat(obs_b), "actions": flat(act_b), "logp": flat(logp_b),
                "adv": flat(adv.astype(np.float32)), "returns": flat(returns.astype(np.float32))}


def _is_async(cfg: TrainConfig) -> bool:
    from loco_il.experts.vec import resolve_async
    return resolve_async(cfg.async_envs, cfg.num_envs)


def train(cfg: TrainConfig | Mapping[str, Any], **overrides: Any) -> dict[str, Any]:
    """Convenience: `train({"task": "Hopper.run", "total_steps": 100_000, "out_dir": "runs/x"})`."""
    if not isinstance(cfg, TrainConfig):
        cfg = TrainConfig.from_mapping(dict(cfg, **overrides))
    elif overrides:
        cfg = dataclasses.replace(cfg, **overrides)
    return PPOTrainer(cfg).train()
