"""On-policy optimization: GAE and TRPO (the optimizer of LocoMuJoCo's GAIL/VAIL baselines).

* `gae`            Generalized Advantage Estimation (Schulman et al. 2016, eq. 16) with mushroom-rl's
                   `absorbing` / `last` flags: an absorbing s' has value 0; a `last` step that is not absorbing
                   (time limit, end of a rollout batch) still bootstraps V(s') but stops the lambda-recursion.
* `trpo_step`      one natural-gradient step (Schulman et al. 2015, "Trust Region Policy Optimization",
                   Appendix C): conjugate gradient on the Fisher-vector product of the mean KL, the step scaled
                   to KL = max_kl under the quadratic model, then a backtracking line search that accepts the
                   first candidate with KL <= max_kl and a surrogate improvement.
* `GaussianFisher` the Fisher-vector product of that step in closed form, F v = J^T M J v (see its
                   docstring): the same matrix as the Hessian of the mean KL that a double backward gives,
                   at about half the cost (CG was ~2/3 of an on-policy fit with the double backward).
* `TRPO`           GAE + trpo_step + a value function fitted by MSE/Adam on the lambda-returns.
* `ObsNormalizedPolicy` a `GaussianPolicy` behind a `RunningNormalizer`; the normalizer is updated
                   only inside `fit` (never while acting), so evaluation does not move it.
"""
from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np
import torch
from torch import nn
from torch.nn.utils import parameters_to_vector, vector_to_parameters

from loco_il.algorithms.common.discriminator import RunningNormalizer
from loco_il.rl.networks import GaussianPolicy, MLPLinearization, mlp, numpy_view


class ObsNormalizedPolicy(nn.Module):
    """`policy(normalizer(obs))` with the `GaussianPolicy` interface the agents use."""

    def __init__(self, policy: GaussianPolicy, obs_dim: int, normalize: bool = True):
        super().__init__()
        self.policy = policy
        self.normalizer = RunningNormalizer(obs_dim)
        self.normalize = normalize
        self.squash = policy.squash

    def norm(self, obs: torch.Tensor) -> torch.Tensor:
        return self.normalizer(obs) if self.normalize else obs

    def _mean_log_std(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Mean and log-std of the action distribution (draw_action uses this, with no distribution object)."""
        return self.policy._mean_log_std(self.norm(obs))

    def distribution(self, obs: torch.Tensor) -> torch.distributions.Normal:
        # built without argument validation
        mean, log_std = self.policy._mean_log_std(self.norm(obs))
        return torch.distributions.Normal(mean, log_std.exp(), validate_args=False)

    def log_prob(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return self.distribution(obs).log_prob(action).sum(-1)

    def deterministic(self, obs: torch.Tensor) -> torch.Tensor:
        return self.policy.deterministic(self.norm(obs))

    def mean_mlp(self, obs: torch.Tensor) -> tuple[nn.Sequential, torch.Tensor]:
        return self.policy.mean_mlp(self.norm(obs))

    def numpy_mean_log_std(self):
        """`GaussianPolicy.numpy_mean_log_std` behind the normalizer (same float32 arithmetic as `norm`)."""
        mean_log_std, tensors = self.policy.numpy_mean_log_std()
        if not self.normalize:
            return mean_log_std, tensors
        n = self.normalizer
        mean, var, eps, clip = numpy_view(n.mean), numpy_view(n.var), n.eps, n.clip

        def normalized(x):
            z = x - mean
            z /= np.sqrt(var + eps)
            return mean_log_std(np.minimum(np.maximum(z, -clip, out=z), clip, out=z))  # = clip, 2x cheaper
        return normalized, tensors + [n.mean, n.var]

    @property
    def log_std(self) -> nn.Parameter:
        return self.policy.log_std


# ---------------------------------------------------------------------------- GAE
def gae(rewards: np.ndarray, values: np.ndarray, next_values: np.ndarray, absorbing: np.ndarray,
        last: np.ndarray, gamma: float, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """Advantages and lambda-returns (value targets) for one batch of consecutive transitions.

    delta_t = r_t + gamma * (1 - absorbing_t) * V(s'_t) - V(s_t)
    A_t     = delta_t + gamma * lam * (1 - last_t) * A_{t+1}
    The final transition of the batch is always treated as `last`.
    """
    rewards = np.asarray(rewards, dtype=np.float64)
    n = rewards.shape[0]
    not_absorbing = 1.0 - np.asarray(absorbing, dtype=np.float64)
    cont = 1.0 - np.asarray(last, dtype=np.float64)
    cont[-1] = 0.0
    values = np.asarray(values, dtype=np.float64)
    deltas = rewards + gamma * not_absorbing * np.asarray(next_values, dtype=np.float64) - values
    adv = np.empty(n)
    running = 0.0
    for t in range(n - 1, -1, -1):
        running = deltas[t] + gamma * lam * cont[t] * running
        adv[t] = running
    return adv, adv + values


# ---------------------------------------------------------------------------- TRPO
def gaussian_kl(old: torch.distributions.Normal, new: torch.distributions.Normal) -> torch.Tensor:
    """Mean over the batch of KL(old || new), summed over action dimensions."""
    return torch.distributions.kl_divergence(old, new).sum(-1).mean()


def conjugate_gradient(avp: Callable[[torch.Tensor], torch.Tensor], b: torch.Tensor,
                       iters: int = 10, residual_tol: float = 1e-10) -> torch.Tensor:
    """Solve A x = b for symmetric positive-definite A given only x -> A x."""
    x = torch.zeros_like(b)
    r, p = b.clone(), b.clone()
    rr = r.dot(r)
    for _ in range(iters):
        if rr < residual_tol:
            break
        ap = avp(p)
        alpha = rr / (p.dot(ap) + 1e-12)
        x += alpha * p
        r -= alpha * ap
        rr_new = r.dot(r)
        p = r + (rr_new / rr) * p
        rr = rr_new
    return x


def surrogate(policy: nn.Module, obs: torch.Tensor, actions: torch.Tensor, advantages: torch.Tensor,
              old_log_prob: torch.Tensor, ent_coef: float = 0.0) -> torch.Tensor:
    """L(theta) = E[pi_theta(a|s) / pi_old(a|s) * A] (+ ent_coef * entropy), to be maximized."""
    ratio = torch.exp(policy.log_prob(obs, actions) - old_log_prob)
    value = (ratio * advantages).mean()
    if ent_coef:
        value = value + ent_coef * policy.distribution(obs).entropy().sum(-1).mean()
    return value


class GaussianFisher:
    """v -> F v for a diagonal Gaussian policy with mean = mlp(input) and a state-independent log-std.

    F is the Hessian of KL_mean(theta) = mean_s KL(pi_old(.|s) || pi_theta(.|s)) at theta = theta_old, the
    matrix TRPO's conjugate gradient needs. For a diagonal Gaussian the Hessian of the KL in the
    distribution parameters (mu, log sigma) at pi = pi_old is diag(1 / sigma^2) for mu, 2 for log sigma and
    0 between them (the first derivatives vanish there), so with J = d mu / d theta_net:

        F v = (1/N) sum_s J_s^T diag(1 / sigma^2) J_s v_net   (+)   2 v_log_std

    exactly the Hessian a double backward of the KL computes, but evaluated as one Jacobian-vector and one
    vector-Jacobian product of the mean network (`MLPLinearization`, whose layer inputs are stored once per
    TRPO step), i.e. 4 matrix products per layer instead of a second-order pass through autograd.
    `params` fixes the order of the flat vectors (the policy's trainable parameters).
    """

    def __init__(self, policy: nn.Module, obs: torch.Tensor, params: Sequence[nn.Parameter]):
        net, x = policy.mean_mlp(obs)
        self.lin = MLPLinearization(net, x)
        self.log_std_param = policy.log_std
        self.params = list(params)
        expected = set(self.lin.parameters()) | {self.log_std_param}
        if set(self.params) != expected or len(self.params) != len(expected):
            raise ValueError("GaussianFisher: the trainable parameters must be exactly those of the mean MLP "
                             "and the log-std")
        self.sizes = [p.numel() for p in self.params]
        log_std = self.log_std_param.detach()
        self.mean, self.std = self.lin.output, log_std.exp().expand_as(self.lin.output)
        self.mean_weight = torch.exp(-2.0 * log_std) / obs.shape[0]  # diag(1/sigma^2) / N, per action dim

    def __call__(self, v: torch.Tensor) -> torch.Tensor:
        tangents = {p: t.view_as(p) for p, t in zip(self.params, v.split(self.sizes))}
        grads = self.lin.vjp(self.lin.jvp(tangents).mul_(self.mean_weight))
        grads[self.log_std_param] = 2.0 * tangents[self.log_std_param]
        return torch.cat([grads[p].reshape(-1) for p in self.params])


def trpo_step(policy: nn.Module, obs: torch.Tensor, actions: torch.Tensor, advantages: torch.Tensor,
              max_kl: float = 5e-3, cg_iters: int = 10, cg_damping: float = 1e-1,
              cg_residual_tol: float = 1e-10, line_search_steps: int = 10, backtrack_coeff: float = 0.5,
              ent_coef: float = 0.0) -> dict:
    """One TRPO update of `policy` in place: an unsquashed `GaussianPolicy` or an `ObsNormalizedPolicy`
    (anything with `distribution(obs)`, `log_prob(obs, a)`, `mean_mlp(obs)` and a `log_std` parameter).

    Returns a dict with the accepted step fraction (0.0: rejected, parameters unchanged), the KL and
    the surrogate improvement.
    """
    params = [p for p in policy.parameters() if p.requires_grad]
    # The parameters do not move during conjugate gradient: the mean network is linearized once (its
    # no-grad forward also gives the old distribution) and every Fisher-vector product reuses it.
    fisher = GaussianFisher(policy, obs, params)
    old_dist = torch.distributions.Normal(fisher.mean, fisher.std, validate_args=False)
    old_log_prob = old_dist.log_prob(actions).sum(-1)

    surr = surrogate(policy, obs, actions, advantages, old_log_prob, ent_coef)
    grad = parameters_to_vector(torch.autograd.grad(surr, params))
    info = {"accepted": 0.0, "kl": 0.0, "improvement": 0.0, "surrogate": surr.item()}
    if not torch.isfinite(grad).all() or grad.norm() < 1e-12:
        return info

    def fisher_vector(v: torch.Tensor) -> torch.Tensor:
        return fisher(v) + cg_damping * v

    direction = conjugate_gradient(fisher_vector, grad, cg_iters, cg_residual_tol)
    shs = direction.dot(fisher_vector(direction))
    if not torch.isfinite(shs) or shs <= 0:
        return info
    full_step = direction * torch.sqrt(2.0 * max_kl / shs)
    old_params = parameters_to_vector(params).detach().clone()

    with torch.no_grad():
        fraction = 1.0
        for _ in range(line_search_steps):
            vector_to_parameters(old_params + fraction * full_step, params)
            dist = policy.distribution(obs)  # one forward for both the surrogate and the KL
            ratio = torch.exp(dist.log_prob(actions).sum(-1) - old_log_prob)
            new_surr = (ratio * advantages).mean()
            if ent_coef:
                new_surr = new_surr + ent_coef * dist.entropy().sum(-1).mean()
            new_surr, kl = new_surr.item(), gaussian_kl(old_dist, dist).item()
            if math.isfinite(new_surr) and kl <= max_kl and new_surr > info["surrogate"]:
                info.update(accepted=fraction, kl=kl, improvement=new_surr - info["surrogate"])
                return info
            fraction *= backtrack_coeff
        vector_to_parameters(old_params, params)  # no acceptable step: keep the old policy
    return info


class TRPO:
    """TRPO with GAE(lambda) and an MSE/Adam value function on the (normalized) observations.

    `update(batch, rewards)` does: V(s), V(s') -> GAE -> standardized advantages -> `trpo_step` ->
    `vf_epochs` passes of minibatch Adam on (V(s) - lambda-return)^2.
    """

    def __init__(self, policy: ObsNormalizedPolicy, obs_dim: int, gamma: float = 0.99, lam: float = 0.97,
                 max_kl: float = 5e-3, cg_iters: int = 25, cg_damping: float = 1e-1,
                 cg_residual_tol: float = 1e-10, line_search_steps: int = 10, ent_coef: float = 0.0,
                 vf_hidden: Sequence[int] = (512, 256), vf_lr: float = 1e-3, vf_epochs: int = 5,
                 vf_batch_size: int = 256, device: torch.device | str = "cpu"):
        self.policy = policy
        self.gamma, self.lam = gamma, lam
        self.step_kwargs = dict(max_kl=max_kl, cg_iters=cg_iters, cg_damping=cg_damping,
                                cg_residual_tol=cg_residual_tol, line_search_steps=line_search_steps,
                                ent_coef=ent_coef)
        self.value_net = mlp(obs_dim, 1, vf_hidden).to(device)
        self.vf_optimizer = torch.optim.Adam(self.value_net.parameters(), lr=vf_lr)
        self.vf_epochs, self.vf_batch_size = vf_epochs, vf_batch_size

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        return self.value_net(self.policy.norm(obs)).squeeze(-1)

    def update(self, obs: torch.Tensor, actions: torch.Tensor, rewards: np.ndarray, next_obs: torch.Tensor,
               absorbing: np.ndarray, last: np.ndarray, generator: np.random.Generator | None = None) -> dict:
        with torch.no_grad():
            v, v_next = self.value(obs).cpu().numpy(), self.value(next_obs).cpu().numpy()
        adv, returns = gae(rewards, v, v_next, absorbing, last, self.gamma, self.lam)
        adv = (adv - adv.mean()) / (adv.std() + 1e-8)
        adv_t = torch.as_tensor(adv, dtype=torch.float32, device=obs.device)
        info = trpo_step(self.policy, obs, actions, adv_t, **self.step_kwargs)
        info["vf_loss"] = self.fit_value(obs, torch.as_tensor(returns, dtype=torch.float32, device=obs.device),
                                         generator or np.random.default_rng())
        return info

    def fit_value(self, obs: torch.Tensor, targets: torch.Tensor, rng: np.random.Generator) -> float:
        n, loss = obs.shape[0], torch.zeros(())
        for _ in range(self.vf_epochs):
            perm = torch.as_tensor(rng.permutation(n), device=obs.device)
            for start in range(0, n, self.vf_batch_size):
                idx = perm[start:start + self.vf_batch_size]
                loss = (self.value(obs[idx]) - targets[idx]).pow(2).mean()
                self.vf_optimizer.zero_grad(set_to_none=True)
                loss.backward()
                self.vf_optimizer.step()
        return float(loss.item())
