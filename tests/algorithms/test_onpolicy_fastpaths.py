"""The on-policy fast paths against the straightforward implementations they replaced.

* `MLPLinearization` (hand-written J t / J^T u of an `mlp`) against torch.func.jvp / autograd;
* `GaussianFisher` (closed-form F v = J^T M J v) against the double backward of the mean KL that
  `trpo_step` used before, and a whole TRPO step with either product;
* the numpy actor of `ILAgent._act` against the torch forward `_act_torch`.
"""
from __future__ import annotations

import numpy as np
import pytest
import torch
from torch import nn
from torch.nn.utils import parameters_to_vector

from loco_il.algorithms.common import onpolicy
from loco_il.rl.networks import GaussianPolicy, MLPLinearization, NumpyMLP, mlp
from loco_il.algorithms.common.onpolicy import ObsNormalizedPolicy, gaussian_kl, trpo_step
from loco_il.algorithms.gail import GAIL
from loco_il.algorithms.sqil import SQIL
from tests.algorithms.test_onpolicy_losses import SMALL, fake_dataset, fake_expert, mdp_info

torch.set_num_threads(1)


def _perturbed(module: nn.Module, seed: int = 0, scale: float = 0.1) -> nn.Module:
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in module.parameters():
            p.add_(scale * torch.randn(p.shape, generator=g))
    return module


def _normalized_policy(obs_dim=5, act_dim=3, hidden=(32, 16), seed=0) -> ObsNormalizedPolicy:
    torch.manual_seed(seed)
    policy = ObsNormalizedPolicy(GaussianPolicy(obs_dim, act_dim, hidden, squash=False, init_log_std=-0.3), obs_dim)
    policy.normalizer.update(torch.randn(200, obs_dim) * 3.0 + 1.0)
    return _perturbed(policy, seed)


class DoubleBackwardFisher:
    """The reference: Hessian-vector products of the mean KL by double backward (trpo_step's old product)."""

    def __init__(self, policy, obs, params):
        self.params = list(params)
        with torch.no_grad():
            old = policy.distribution(obs)
            self.mean, self.std = old.loc.clone(), old.scale.clone()
        kl = gaussian_kl(torch.distributions.Normal(self.mean, self.std), policy.distribution(obs))
        self.g_kl = parameters_to_vector(torch.autograd.grad(kl, self.params, create_graph=True))

    def __call__(self, v):
        return parameters_to_vector(torch.autograd.grad(self.g_kl.dot(v), self.params, retain_graph=True))


# ---------------------------------------------------------------------------- MLPLinearization
@pytest.mark.parametrize("activation", [nn.ReLU, nn.Tanh, nn.ELU], ids=["relu", "tanh", "elu"])
@pytest.mark.parametrize("in_dim", [3, 40], ids=["narrow-input", "wide-input"])
def test_mlp_linearization_matches_autograd(activation, in_dim):
    torch.manual_seed(0)
    net = mlp(in_dim, 4, (24, 16), activation)
    x = torch.randn(64, in_dim)
    params = list(net.parameters())
    tangents = [torch.randn_like(p) for p in params]
    lin = MLPLinearization(net, x)
    assert torch.allclose(lin.output, net(x), atol=1e-6)

    names = [n for n, _ in net.named_parameters()]
    out, jt = torch.func.jvp(lambda *ps: torch.func.functional_call(net, dict(zip(names, ps)), (x,)),
                             tuple(p.detach() for p in params), tuple(tangents))
    assert torch.allclose(lin.jvp(dict(zip(params, tangents))), jt, atol=1e-5)

    u = torch.randn_like(out)
    ref = torch.autograd.grad(net(x), params, grad_outputs=u)
    mine = lin.vjp(u)
    for p, r in zip(params, ref):
        assert torch.allclose(mine[p], r, atol=1e-5)


def test_mlp_linearization_rejects_unknown_layers():
    with pytest.raises(TypeError, match="LayerNorm"):
        MLPLinearization(nn.Sequential(nn.Linear(3, 4), nn.LayerNorm(4), nn.Linear(4, 1)), torch.randn(2, 3))


# ---------------------------------------------------------------------------- Fisher-vector product
@pytest.mark.parametrize("normalized", [True, False], ids=["obs-normalized", "plain-gaussian"])
def test_gaussian_fisher_equals_double_backward_of_the_kl(normalized):
    if normalized:
        policy = _normalized_policy()
    else:
        torch.manual_seed(1)
        policy = _perturbed(GaussianPolicy(5, 3, (32, 16), squash=False, init_log_std=0.4), 1)
    obs = torch.randn(256, 5) * 2.0
    params = [p for p in policy.parameters() if p.requires_grad]
    fast, ref = onpolicy.GaussianFisher(policy, obs, params), DoubleBackwardFisher(policy, obs, params)
    assert torch.allclose(fast.mean, ref.mean, atol=1e-6) and torch.allclose(fast.std, ref.std)
    for seed in range(3):
        v = torch.randn(sum(p.numel() for p in params), generator=torch.Generator().manual_seed(seed))
        f, r = fast(v), ref(v)
        assert (f - r).abs().max() <= 1e-5 * max(1.0, r.abs().max().item())


def test_trpo_step_same_parameters_with_either_fisher_product(monkeypatch):
    policy = _normalized_policy(hidden=(64, 32), seed=2)
    obs = torch.randn(512, 5) * 2.0
    with torch.no_grad():
        actions = policy.distribution(obs).sample()
    advantages = (actions[:, 0] - actions[:, 0].mean()) / actions[:, 0].std()
    start = {k: v.clone() for k, v in policy.state_dict().items()}
    kwargs = dict(max_kl=1e-2, cg_iters=25, cg_damping=0.1)

    info_fast = trpo_step(policy, obs, actions, advantages, **kwargs)
    fast = parameters_to_vector(policy.parameters()).detach().clone()
    policy.load_state_dict(start)
    monkeypatch.setattr(onpolicy, "GaussianFisher", DoubleBackwardFisher)
    info_ref = trpo_step(policy, obs, actions, advantages, **kwargs)
    ref = parameters_to_vector(policy.parameters()).detach()

    assert info_fast["accepted"] == info_ref["accepted"] > 0
    assert info_fast["kl"] == pytest.approx(info_ref["kl"], rel=1e-4)
    assert (fast - ref).abs().max() <= 1e-5


# ---------------------------------------------------------------------------- numpy actor
def test_numpy_mlp_matches_torch_forward():
    torch.manual_seed(0)
    for activation in (nn.ReLU, nn.Tanh):
        net = mlp(7, 4, (64, 32), activation)
        x = torch.randn(7)
        assert np.allclose(NumpyMLP(net)(x.numpy()), net(x).detach().numpy(), atol=1e-5)
    with pytest.raises(TypeError):
        NumpyMLP(mlp(7, 4, (8,), nn.ELU))


def _gail(seed=0):
    torch.manual_seed(seed)  # the policy's initial weights
    agent = GAIL(mdp_info(), GaussianPolicy(4, 1, hidden=(32, 16), squash=False), seed=seed, **SMALL)
    agent.set_expert(fake_expert())
    return agent


def _sqil(seed=0):
    torch.manual_seed(seed)
    return SQIL(mdp_info(), GaussianPolicy(4, 1, hidden=(32, 16), squash=True), seed=seed)


def _assert_numpy_actor_matches_torch(agent, states):
    assert agent._numpy_mean_log_std() is not None  # the numpy path is the one under test
    module = agent.policy_module
    for s in states:
        mean, log_std = agent._numpy_mean_log_std()(s.astype(np.float32))
        t_mean, t_log_std = module._mean_log_std(torch.as_tensor(s, dtype=torch.float32).reshape(1, -1))
        assert np.allclose(mean, t_mean[0].detach().numpy(), atol=1e-5)
        assert np.allclose(log_std, t_log_std[0].detach().numpy(), atol=1e-6)
        for deterministic in (True, False):
            agent.deterministic = deterministic
            state = agent.torch_generator.get_state()
            a_numpy = agent._act(s)
            agent.torch_generator.set_state(state)
            a_torch = agent._act_torch(s)
            assert a_numpy.dtype == np.float64 and a_numpy.shape == a_torch.shape
            assert np.allclose(a_numpy, a_torch, atol=1e-5)
    agent.deterministic = False


@pytest.mark.parametrize("make", [_gail, _sqil], ids=["gail-obs-normalized", "sqil-squashed"])
def test_numpy_actor_same_actions_as_torch_forward(make):
    agent = make()
    states = np.random.default_rng(0).normal(size=(10, 4)) * 3
    _assert_numpy_actor_matches_torch(agent, states)
    # reproducible from the seed: a second agent draws the same actions
    twin1, twin2 = make(seed=5), make(seed=5)
    seq1, seq2 = [twin1.draw_action(s) for s in states], [twin2.draw_action(s) for s in states]
    assert all(np.array_equal(x, y) for x, y in zip(seq1, seq2))


def test_numpy_actor_follows_fits_optimizer_steps_and_checkpoints(tmp_path):
    agent = _gail()
    states = np.random.default_rng(1).normal(size=(4, 4)) * 2
    agent.draw_action(states[0])  # builds the numpy actor
    agent.fit(fake_dataset())  # TRPO replaces the parameter storages, the normalizer moves in place
    _assert_numpy_actor_matches_torch(agent, states)
    with torch.no_grad():  # an in-place change of a parameter and of the normalizer
        agent.policy_module.policy.net[0].weight.mul_(1.5)
        agent.policy_module.normalizer.mean.add_(0.3)
    _assert_numpy_actor_matches_torch(agent, states)
    other = _gail(seed=3)
    other.fit(fake_dataset(seed=4))
    other.save(tmp_path / "other.pt")
    agent.load(tmp_path / "other.pt")
    _assert_numpy_actor_matches_torch(agent, states)
    agent.deterministic = other.deterministic = True
    assert np.allclose(agent.draw_action(states[0]), other.draw_action(states[0]), atol=1e-6)


def test_numpy_actor_off_for_unsupported_policies():
    agent = GAIL(mdp_info(), GaussianPolicy(4, 1, hidden=(8,), squash=False, activation=nn.ELU), seed=0, **SMALL)
    assert agent._numpy_mean_log_std() is None
    assert agent.draw_action(np.ones(4)).shape == (1,)
