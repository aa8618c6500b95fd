"""Network building blocks shared by every algorithm.

Kept deliberately small: an MLP builder, a diagonal Gaussian policy (optionally
tanh-squashed, as SAC needs), a Q critic of one or more heads (SAC's twin critic),
`NumpyMLP` (an `mlp` forward for one observation on numpy views of the parameters, for acting)
and `MLPLinearization` (hand-written Jacobian-vector products of an `mlp`, for TRPO's
Fisher-vector products). Algorithms compose these; none of them defines its own copy.
"""
from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np
import torch
from torch import nn

LOG_STD_MIN, LOG_STD_MAX = -20.0, 2.0


def mlp(in_dim: int, out_dim: int, hidden: Sequence[int] = (256, 256),
        activation: type[nn.Module] = nn.ReLU, out_gain: float | None = None,
        layer_norm: bool = False) -> nn.Sequential:
    """A plain feed-forward network; `out_gain` scales the last layer's init (small for policies).

    layer_norm=True puts an `nn.LayerNorm` between each hidden Linear layer and its activation (the critic
    of Ball et al. 2023, "Efficient Online RL with Offline Data": it bounds how far Q extrapolates).
    """
    layers: list[nn.Module] = []
    last = in_dim
    for width in hidden:
        layers += [nn.Linear(last, width), *([nn.LayerNorm(width)] if layer_norm else []), activation()]
        last = width
    out = nn.Linear(last, out_dim)
    if out_gain is not None:
        nn.init.orthogonal_(out.weight, gain=out_gain)
        nn.init.zeros_(out.bias)
    layers.append(out)
    return nn.Sequential(*layers)


class GaussianPolicy(nn.Module):
    """Diagonal Gaussian policy.

    squash=True gives SAC's tanh-squashed policy with a state-dependent std;
    squash=False gives the PPO/TRPO/BC policy with a state-independent log-std.
    Actions live in [-1, 1] (the environments' normalized action space).
    `log_std_bounds` clamps the squashed policy's state-dependent log-std (SAC's usual (-20, 2); the LS-IQ
    authors' released runs use (-5, 2)); the unsquashed policy's log-std is a free parameter, not clamped.
    """

    def __init__(self, obs_dim: int, act_dim: int, hidden: Sequence[int] = (256, 256),
                 squash: bool = True, init_log_std: float = 0.0,
                 activation: type[nn.Module] = nn.ReLU,
                 log_std_bounds: tuple[float, float] = (LOG_STD_MIN, LOG_STD_MAX)):
        super().__init__()
        self.squash = squash
        self.act_dim = act_dim
        self.log_std_min, self.log_std_max = (float(b) for b in log_std_bounds)
        if not self.log_std_min < self.log_std_max:
            raise ValueError(f"GaussianPolicy: log_std_bounds must be (min, max) with min < max, got {log_std_bounds}")
        if squash:
            self.net = mlp(obs_dim, 2 * act_dim, hidden, activation)
        else:
            self.net = mlp(obs_dim, act_dim, hidden, activation, out_gain=0.01)
            self.log_std = nn.Parameter(torch.full((act_dim,), float(init_log_std)))

    def _mean_log_std(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        out = self.net(obs)
        if self.squash:
            mean, log_std = out.chunk(2, dim=-1)
            return mean, log_std.clamp(self.log_std_min, self.log_std_max)
        return out, self.log_std.expand_as(out)

    def distribution(self, obs: torch.Tensor) -> torch.distributions.Normal:
        mean, log_std = self._mean_log_std(obs)
        return torch.distributions.Normal(mean, log_std.exp(), validate_args=False)  # no per-call checks on the hot path

    def sample(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Reparameterized sample and its log-probability (summed over action dims)."""
        return self.sample_from(*self._mean_log_std(obs))

    def sample_from(self, mean: torch.Tensor, log_std: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """`sample` from a forward already taken (`_mean_log_std`): an update that needs actions at the same
        states twice (the critic's V(s), then the actor step) runs the network once and draws twice."""
        std = log_std.exp()
        noise = torch.randn_like(mean)
        pre = mean + std * noise
        log_prob = (-0.5 * noise.pow(2) - log_std - 0.5 * math.log(2 * math.pi)).sum(-1)
        if not self.squash:
            return pre, log_prob
        action = torch.tanh(pre)
        # change of variables for tanh, in the numerically stable form
        log_prob = log_prob - (2 * (math.log(2) - pre - nn.functional.softplus(-2 * pre))).sum(-1)
        return action, log_prob

    def log_prob(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        """Log-probability of given actions (unsquashed policies only: PPO, TRPO, BC)."""
        if self.squash:
            raise ValueError("log_prob of a tanh-squashed policy is not used by any algorithm here")
        return self.distribution(obs).log_prob(action).sum(-1)

    def deterministic(self, obs: torch.Tensor) -> torch.Tensor:
        mean, _ = self._mean_log_std(obs)
        return torch.tanh(mean) if self.squash else mean

    def numpy_mean_log_std(self) -> tuple[Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], list]:
        """`_mean_log_std` for ONE float32 observation (shape (obs_dim,)) in numpy, on views of the
        parameters (see `NumpyMLP`), and the tensors viewed. Raises TypeError when not possible."""
        net = NumpyMLP(self.net)
        if self.squash:
            act_dim, lo, hi = self.act_dim, self.log_std_min, self.log_std_max

            def mean_log_std(x):
                out = net(x)
                return out[:act_dim], np.clip(out[act_dim:], lo, hi)
            return mean_log_std, net.tensors
        log_std = numpy_view(self.log_std)
        return (lambda x: (net(x), log_std)), net.tensors + [self.log_std]

    def mean_mlp(self, obs: torch.Tensor) -> tuple[nn.Sequential, torch.Tensor]:
        """The network whose output is the mean, and its input for `obs` (unsquashed policies:
        mean = net(input), std = exp(log_std)); TRPO linearizes it for its Fisher-vector products."""
        if self.squash:
            raise ValueError("mean_mlp: a tanh-squashed policy has no separate mean network")
        return self.net, obs


class EnsembleQ(nn.Module):
    """`n_heads` independent Q-networks evaluated in one call: a (n_heads, batch) tensor of Q_i(s, a).

    n_heads=2 is SAC's twin critic (Haarnoja et al. 2018b; learners take the minimum of the heads);
    n_heads=1 a single critic (as in the LS-IQ authors' released runs); layer_norm: see `mlp`. Heads are named
    q1, q2, ... so the state dicts of twin critics saved before `n_heads` existed load unchanged.
    """

    def __init__(self, obs_dim: int, act_dim: int, hidden: Sequence[int] = (256, 256),
                 activation: type[nn.Module] = nn.ReLU, n_heads: int = 2, layer_norm: bool = False):
        super().__init__()
        if int(n_heads) < 1:
            raise ValueError(f"EnsembleQ: n_heads must be >= 1, got {n_heads}")
        for i in range(int(n_heads)):
            self.add_module(f"q{i + 1}", mlp(obs_dim + act_dim, 1, hidden, activation, layer_norm=layer_norm))

    @property
    def n_heads(self) -> int:
        return len(self._modules)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        x = torch.cat([obs, action], dim=-1)
        return torch.stack([head(x).squeeze(-1) for head in self.children()])


def numpy_view(t: torch.Tensor) -> np.ndarray:
    """A numpy array sharing memory with a float32 CPU tensor: it follows in-place updates (optimizer steps,
    `load_state_dict`), not a replaced storage (`param.data = ...`; compare `data_ptr()` to detect that)."""
    if t.device.type != "cpu" or t.dtype != torch.float32:
        raise TypeError(f"numpy_view: needs a float32 CPU tensor, got {t.dtype} on {t.device}")
    return t.detach().numpy()


class NumpyMLP:
    """`net(x)` for one input vector with numpy on views of the parameters (float32, as torch computes).

    For a single observation a torch forward is dominated by per-op dispatch (~100 us for a [512, 256]
    policy), numpy's matrix-vector products by the arithmetic (~15 us), which matters because agents act
    once per environment step. `tensors` lists the viewed tensors (to detect a replaced storage).
    Supports `nn.Linear`, ReLU, Tanh and Identity; raises TypeError otherwise.
    """

    _ACTIVATIONS = {nn.ReLU: lambda h: np.maximum(h, 0.0, out=h), nn.Tanh: lambda h: np.tanh(h, out=h),
                    nn.Identity: lambda h: h}

    def __init__(self, net: nn.Sequential):
        self.tensors: list[torch.Tensor] = []
        self.layers: list = []
        for module in net:
            if isinstance(module, nn.Linear):
                if module.bias is None:
                    raise TypeError("NumpyMLP: Linear layers without bias are not supported")
                self.tensors += [module.weight, module.bias]
                self.layers.append((numpy_view(module.weight), numpy_view(module.bias)))
            elif type(module) in self._ACTIVATIONS:
                self.layers.append(self._ACTIVATIONS[type(module)])
            else:
                raise TypeError(f"NumpyMLP: unsupported layer {type(module).__name__}")

    def __call__(self, x: np.ndarray) -> np.ndarray:
        h = x
        for layer in self.layers:
            if isinstance(layer, tuple):
                w, b = layer
                h = w @ h
                h += b
            else:
                h = layer(h)
        return h


#: element-wise activations whose Jacobian is diagonal (MLPLinearization takes their derivative by autograd)
ELEMENTWISE_ACTIVATIONS = (nn.ReLU, nn.Tanh, nn.ELU, nn.LeakyReLU, nn.SiLU, nn.GELU, nn.Sigmoid, nn.Softplus,
                           nn.Identity)


class MLPLinearization:
    """The first-order expansion of an `mlp(...)` network (`nn.Sequential` of `nn.Linear` and element-wise
    activations) in its parameters, around the current parameters and at fixed inputs `x`.

    `jvp(tangents)` = J t: the change of `net(x)` along a parameter direction t (a dict parameter ->
    tangent); `vjp(u)` = J^T u: the gradient of sum(u * net(x)) per parameter. Both reuse the layer inputs
    and activation derivatives stored at construction, so each costs two matrix products per `Linear`
    layer (autograd's forward mode would redo the forward pass and a double backward costs about twice as
    much): TRPO calls them 25+ times per update with the parameters fixed (`onpolicy.GaussianFisher`).
    The parameters must not change while the object is in use.
    """

    def __init__(self, net: nn.Sequential, x: torch.Tensor):
        if not isinstance(net, nn.Sequential):
            raise TypeError(f"MLPLinearization needs an nn.Sequential (an `mlp`), got {type(net).__name__}")
        self.linears: list[nn.Linear] = []
        self.inputs: list[torch.Tensor] = []  # input of each Linear layer
        self.derivs: list[torch.Tensor | None] = []  # derivative of the activations that follow it (None: none)
        h = x.detach()
        with torch.no_grad():
            for module in net:
                if isinstance(module, nn.Linear):
                    self.linears.append(module)
                    self.inputs.append(h)
                    self.derivs.append(None)
                    h = module(h)
                elif isinstance(module, ELEMENTWISE_ACTIVATIONS):
                    if not self.linears:
                        raise TypeError("MLPLinearization: the network must start with an nn.Linear")
                    if isinstance(module, nn.ReLU):  # the common case, without an autograd call
                        d = (h > 0).to(h.dtype)
                        h = module(h)
                    else:
                        with torch.enable_grad():
                            pre = h.detach().requires_grad_(True)
                            out = module(pre)
                            d, = torch.autograd.grad(out.sum(), pre)  # diagonal Jacobian
                        h = out.detach()
                    prev = self.derivs[-1]
                    self.derivs[-1] = d if prev is None else prev * d
                else:
                    raise TypeError(f"MLPLinearization: unsupported layer {type(module).__name__} "
                                    f"(only nn.Linear and element-wise activations {ELEMENTWISE_ACTIVATIONS})")
        self.output = h

    def parameters(self) -> list[nn.Parameter]:
        return [p for lin in self.linears for p in (lin.weight, lin.bias) if p is not None]

    def jvp(self, tangents: dict) -> torch.Tensor:
        """J t for the parameter tangents `tangents[param]` (every parameter of the network must be a key)."""
        dh = None
        for lin, xin, d in zip(self.linears, self.inputs, self.derivs):
            out = xin @ tangents[lin.weight].t()
            if lin.bias is not None:
                out += tangents[lin.bias]
            if dh is not None:
                out.addmm_(dh, lin.weight.detach().t())
            dh = out if d is None else out.mul_(d)
        return dh

    def vjp(self, u: torch.Tensor) -> dict:
        """J^T u as a dict parameter -> gradient (u has the shape of the network's output)."""
        grads = {}
        g = u
        for k in range(len(self.linears) - 1, -1, -1):
            lin = self.linears[k]
            if self.derivs[k] is not None:
                g = g * self.derivs[k] if g is u else g.mul_(self.derivs[k])  # never modify the caller's u
            x = self.inputs[k]
            # same product, in the order BLAS runs fastest (long output rows): 4x faster for a narrow input
            grads[lin.weight] = g.t() @ x if x.shape[1] >= g.shape[1] else (x.t() @ g).t()
            if lin.bias is not None:
                grads[lin.bias] = g.sum(0)
            if k:
                g = g @ lin.weight.detach()
        return grads
