"""Unit tests of the adversarial / on-policy pieces on hand-made tensors (numbers worked out by hand)."""
from __future__ import annotations

import math
import types

import numpy as np
import pytest
import torch
from mushroom_rl.core import MDPInfo
from mushroom_rl.utils.spaces import Box

from loco_il.algorithms.bc import BC, bc_loss
from loco_il.algorithms.common.discriminator import (Discriminator, RunningNormalizer, VariationalDiscriminator,
                                                     discriminator_loss, gail_reward, vail_beta_update, vail_kl,
                                                     vail_loss)
from loco_il.rl.networks import GaussianPolicy
from loco_il.algorithms.common.onpolicy import (ObsNormalizedPolicy, conjugate_gradient, gae, gaussian_kl,
                                                surrogate, trpo_step)
from loco_il.algorithms.gaifo import GAIfO
from loco_il.algorithms.gail import GAIL
from loco_il.algorithms.vail import VAIL

torch.set_num_threads(1)
LN3 = math.log(3.0)


# ---------------------------------------------------------------------------- discriminator loss / reward
def test_onpolicy_discriminator_loss_hand_computed():
    # D = sigmoid(logit): expert logits 0, ln3 -> D = 1/2, 3/4; agent logits 0, -ln3 -> D = 1/2, 1/4
    # -mean(log 1/2, log 3/4) - mean(log(1 - 1/2), log(1 - 1/4)) = ln2 + ln(4/3) = 0.980829
    loss = discriminator_loss(torch.tensor([0.0, LN3]), torch.tensor([0.0, -LN3]))
    assert loss.item() == pytest.approx(math.log(2) + math.log(4 / 3), abs=1e-6)
    assert loss.item() == pytest.approx(0.980829, abs=1e-6)
    # labels matter: a discriminator that is right has a lower loss than one that is wrong
    right = discriminator_loss(torch.tensor([3.0]), torch.tensor([-3.0]))
    wrong = discriminator_loss(torch.tensor([-3.0]), torch.tensor([3.0]))
    assert right.item() == pytest.approx(2 * math.log1p(math.exp(-3)), abs=1e-6)
    assert wrong.item() == pytest.approx(2 * (3 + math.log1p(math.exp(-3))), abs=1e-5)


def test_onpolicy_gail_reward_hand_computed():
    # r = -log(1 - D): D = 1/2 -> ln2, D = 3/4 -> ln4, D = 1/4 -> ln(4/3)
    r = gail_reward(torch.tensor([0.0, LN3, -LN3]))
    assert r.tolist() == pytest.approx([math.log(2), math.log(4), math.log(4 / 3)], abs=1e-6)
    # increasing in D, always positive, finite for extreme logits
    big = gail_reward(torch.tensor([-100.0, 100.0]))
    assert torch.isfinite(big).all() and big[0] > 0 and big[1].item() == pytest.approx(100.0)


# ---------------------------------------------------------------------------- VAIL
def test_onpolicy_vail_kl_known_gaussian():
    # mu = (1, 0), sigma = (1, 2): 0.5 * [(1 + 1 - 1 - 0) + (0 + 4 - 1 - 2 ln 2)] = 2 - ln 2 = 1.306853
    kl = vail_kl(torch.tensor([[1.0, 0.0]]), torch.tensor([[0.0, math.log(2.0)]]))
    assert kl.shape == (1,)
    assert kl.item() == pytest.approx(2 - math.log(2), abs=1e-6)
    assert vail_kl(torch.zeros(3, 5), torch.zeros(3, 5)).abs().max().item() == 0.0
    mu, sigma = torch.tensor([0.3, -1.0]), torch.tensor([0.5, 1.5])
    Normal = torch.distributions.Normal
    ref = torch.distributions.kl_divergence(Normal(mu, sigma), Normal(0.0, 1.0)).sum()
    assert vail_kl(mu, sigma.log()).item() == pytest.approx(ref.item(), abs=1e-6)


def test_onpolicy_vail_beta_update_direction_and_clipping():
    assert vail_beta_update(0.1, kl=1.0, i_c=0.5, lr=0.1) == pytest.approx(0.15)  # KL above I_c -> beta grows
    assert vail_beta_update(0.1, kl=0.0, i_c=0.5, lr=0.1) == pytest.approx(0.05)  # below -> beta shrinks
    assert vail_beta_update(0.01, kl=0.0, i_c=0.5, lr=0.1) == 0.0                 # never below 0
    assert vail_beta_update(0.0, kl=0.0, i_c=0.5, lr=1.0) == 0.0


def test_onpolicy_vail_loss_adds_constraint_term():
    le, la = torch.tensor([0.0, LN3]), torch.tensor([0.0, -LN3])
    kl_e, kl_a = torch.tensor([1.0, 3.0]), torch.tensor([0.0, 0.0])  # mixture mean KL = 1.0
    loss, mean_kl = vail_loss(le, la, kl_e, kl_a, beta=0.5, i_c=0.2)
    assert mean_kl.item() == pytest.approx(1.0)
    assert loss.item() == pytest.approx(0.980829 + 0.5 * (1.0 - 0.2), abs=1e-6)


def test_onpolicy_vail_agent_beta_follows_kl():
    agent = VAIL(mdp_info(), small_policy(), seed=0, z_dim=4, info_constraint=0.0, beta_lr=0.1,
                 beta_init=0.0, **SMALL)
    agent.set_expert(fake_expert())
    agent.fit(fake_dataset())
    assert agent.beta > 0.0  # any positive KL above I_c = 0 raises beta
    assert agent.last_fit_info["vail_beta"] == agent.beta


# ---------------------------------------------------------------------------- GAE
REW, V, V_NEXT = [1.0, 2.0, 3.0], [0.5, 1.0, 1.5], [1.0, 1.5, 2.0]


def test_onpolicy_gae_absorbing_end():
    # gamma 0.9, lambda 0.8 (gamma * lambda = 0.72); s'_2 absorbing -> V(s'_2) counts as 0
    # delta = (1 + .9*1 - .5, 2 + .9*1.5 - 1, 3 - 1.5) = (1.4, 2.35, 1.5)
    # A_2 = 1.5; A_1 = 2.35 + .72*1.5 = 3.43; A_0 = 1.4 + .72*3.43 = 3.8696
    adv, ret = gae(REW, V, V_NEXT, absorbing=[False, False, True], last=[False, False, True], gamma=0.9, lam=0.8)
    assert adv == pytest.approx([3.8696, 3.43, 1.5])
    assert ret == pytest.approx([3.8696 + 0.5, 3.43 + 1.0, 1.5 + 1.5])


def test_onpolicy_gae_truncated_end_bootstraps():
    # last without absorbing (time limit): delta_2 = 3 + .9*2 - 1.5 = 3.3
    # A_1 = 2.35 + .72*3.3 = 4.726; A_0 = 1.4 + .72*4.726 = 4.80272
    adv, _ = gae(REW, V, V_NEXT, absorbing=[False, False, False], last=[False, False, True], gamma=0.9, lam=0.8)
    assert adv == pytest.approx([4.80272, 4.726, 3.3])


def test_onpolicy_gae_episode_boundary_and_batch_end():
    # episode ends (truncated) at t=1, a new one starts at t=2 and is cut by the batch end:
    # A_2 = 3.3 (bootstrapped, batch end acts as last); A_1 = 2.35 (no recursion across the boundary);
    # A_0 = 1.4 + .72*2.35 = 3.092
    adv, _ = gae(REW, V, V_NEXT, absorbing=[False, False, False], last=[False, True, False], gamma=0.9, lam=0.8)
    assert adv == pytest.approx([3.092, 2.35, 3.3])


# ---------------------------------------------------------------------------- TRPO
def test_onpolicy_conjugate_gradient_solves_spd_system():
    a = torch.tensor([[4.0, 1.0], [1.0, 3.0]])
    x = conjugate_gradient(lambda v: a @ v, torch.tensor([1.0, 2.0]), iters=10)
    assert x.tolist() == pytest.approx([1 / 11, 7 / 11], abs=1e-5)


def _trpo_problem(seed=0):
    torch.manual_seed(seed)
    policy = GaussianPolicy(3, 2, hidden=(16,), squash=False, init_log_std=-0.5)
    obs = torch.randn(512, 3)
    with torch.no_grad():
        actions = policy.distribution(obs).sample()
    advantages = (actions[:, 0] - actions[:, 0].mean()) / actions[:, 0].std()  # prefers larger a_0
    return policy, obs, actions, advantages


@pytest.mark.parametrize("max_kl", [1e-3, 1e-2])
def test_onpolicy_trpo_step_respects_kl_and_improves(max_kl):
    policy, obs, actions, advantages = _trpo_problem()
    with torch.no_grad():
        old = policy.distribution(obs)
        old = torch.distributions.Normal(old.loc.clone(), old.scale.clone())
        old_logp = old.log_prob(actions).sum(-1)
        surr_before = surrogate(policy, obs, actions, advantages, old_logp).item()
        mean_a0_before = old.loc[:, 0].mean().item()
    info = trpo_step(policy, obs, actions, advantages, max_kl=max_kl, cg_iters=10, cg_damping=1e-2)
    with torch.no_grad():
        kl = gaussian_kl(old, policy.distribution(obs)).item()
        surr_after = surrogate(policy, obs, actions, advantages, old_logp).item()
        mean_a0_after = policy.distribution(obs).loc[:, 0].mean().item()
    assert info["accepted"] > 0
    assert 0 < kl <= 1.5 * max_kl
    assert surr_after > surr_before
    assert mean_a0_after > mean_a0_before  # moved toward the advantaged direction
    assert info["kl"] == pytest.approx(kl, rel=1e-4)


def test_onpolicy_trpo_step_zero_advantage_keeps_policy():
    policy, obs, actions, _ = _trpo_problem()
    before = [p.detach().clone() for p in policy.parameters()]
    info = trpo_step(policy, obs, actions, torch.zeros(obs.shape[0]), max_kl=1e-2)
    assert info["accepted"] == 0.0
    assert all(torch.equal(a, b) for a, b in zip(before, policy.parameters()))


# ---------------------------------------------------------------------------- normalizer
def test_onpolicy_normalizer_running_stats_and_frozen_in_eval():
    norm = RunningNormalizer(2)
    rng = np.random.default_rng(0)
    a, b = rng.normal(3.0, 2.0, size=(50, 2)), rng.normal(-1.0, 0.5, size=(30, 2))
    norm.update(torch.as_tensor(a, dtype=torch.float32))
    norm.update(torch.as_tensor(b, dtype=torch.float32))
    both = np.concatenate([a, b])
    assert norm.mean.numpy() == pytest.approx(both.mean(0), abs=1e-4)
    assert norm.var.numpy() == pytest.approx(both.var(0), rel=1e-4)
    frozen = {k: v.clone() for k, v in norm.state_dict().items()}
    norm.eval()
    norm.update(torch.full((10, 2), 100.0))
    assert all(torch.equal(frozen[k], v) for k, v in norm.state_dict().items())
    out = norm(torch.as_tensor(both[:3], dtype=torch.float32))
    assert out.numpy() == pytest.approx((both[:3] - both.mean(0)) / both.std(0), abs=1e-3)


def test_onpolicy_agent_normalizers_do_not_move_while_acting():
    agent = GAIL(mdp_info(), small_policy(), seed=0, **SMALL)
    agent.set_expert(fake_expert())
    agent.fit(fake_dataset())
    snapshot = {k: v.clone() for k, v in agent.state_dict()["policy"].items()}
    disc_snapshot = {k: v.clone() for k, v in agent.discriminator.state_dict().items()}
    for deterministic in (False, True):
        agent.deterministic = deterministic
        for _ in range(20):
            agent.draw_action(np.random.default_rng(1).normal(size=4) * 50)
    assert all(torch.equal(snapshot[k], v) for k, v in agent.policy_module.state_dict().items())
    assert all(torch.equal(disc_snapshot[k], v) for k, v in agent.discriminator.state_dict().items())
    count = agent.policy_module.normalizer.count.item()
    agent.fit(fake_dataset(seed=3))
    assert agent.policy_module.normalizer.count.item() > count  # ... but they do move in fit


# ---------------------------------------------------------------------------- discriminator inputs
def test_onpolicy_discriminator_input_kinds():
    obs, act = torch.randn(5, 4), torch.randn(5, 1)
    assert Discriminator(4, 1, use_actions=True)(obs, act).shape == (5,)
    assert Discriminator(4, 1, use_actions=False)(obs).shape == (5,)
    assert Discriminator(4, 1, use_actions=False, use_next_states=True)(obs, None, obs).shape == (5,)
    assert VariationalDiscriminator(4, 1, use_actions=True, z_dim=3)(obs, act).shape == (5,)
    with pytest.raises(ValueError, match="actions"):
        Discriminator(4, 1, use_actions=True)(obs)


# ---------------------------------------------------------------------------- agents: helpers
SMALL = dict(disc_hidden=(8,), disc_batch_size=64, train_disc_every=1, vf_hidden=(8,), vf_epochs=1, cg_iters=3)


def mdp_info():
    return MDPInfo(Box(np.full(4, -np.inf), np.full(4, np.inf)), Box(-np.ones(1), np.ones(1)), 0.99, 100)


def small_policy():
    return GaussianPolicy(4, 1, hidden=(8,), squash=False)


def fake_expert(n=200, actions=True, seed=0):
    rng = np.random.default_rng(seed)
    obs = rng.normal(size=(n, 4))
    last = np.zeros(n, dtype=bool)
    last[49::50] = True
    return types.SimpleNamespace(obs=obs, next_obs=obs + 0.1, actions=np.tanh(obs[:, :1]) if actions else None,
                                 rewards=np.ones(n), absorbing=np.zeros(n, dtype=bool), last=last)


def fake_dataset(n=128, seed=1):
    rng = np.random.default_rng(seed)
    rows = []
    for t in range(n):
        s = rng.normal(size=4)
        rows.append((s, rng.normal(size=1), 1.0, s + 0.1, t == 60, t in (60, n - 1)))
    return rows


# ---------------------------------------------------------------------------- checkpoints
@pytest.mark.parametrize("algo,real", [(GAIL, False), (GAIL, True), (VAIL, False), (GAIfO, True)],
                         ids=["gail", "gail-state-only", "vail", "gaifo"])
def test_onpolicy_state_dict_round_trip(tmp_path, algo, real):
    kw = dict(SMALL, **({"z_dim": 3} if algo is VAIL else {}))
    agent = algo(mdp_info(), small_policy(), seed=0, **kw)
    agent.set_expert(fake_expert(actions=not real))
    for seed in (1, 2):
        agent.fit(fake_dataset(seed=seed))
    agent.save(tmp_path / "agent.pt")
    clone = algo.load(tmp_path / "agent.pt")
    assert clone.n_fits == agent.n_fits == 2
    assert clone.discriminator.input_kind == agent.discriminator.input_kind
    obs = torch.randn(6, 4)
    acts = torch.rand(6, 1) * 2 - 1
    assert torch.allclose(clone.reward(obs, acts, obs + 0.1), agent.reward(obs, acts, obs + 0.1))
    assert torch.allclose(clone.trpo.value(obs), agent.trpo.value(obs))
    agent.deterministic = clone.deterministic = True
    state = np.arange(4.0)
    assert np.allclose(clone.draw_action(state), agent.draw_action(state))
    if algo is VAIL:
        assert clone.beta == agent.beta
    # the loaded agent keeps training from the same state
    clone.set_expert(fake_expert(actions=not real))
    clone.fit(fake_dataset(seed=3))
    assert clone.n_fits == 3


def test_onpolicy_bc_state_dict_round_trip(tmp_path):
    agent = BC(mdp_info(), small_policy(), seed=0, batch_size=32)
    agent.set_expert(fake_expert())
    agent.pretrain(5)
    agent.save(tmp_path / "bc.pt")
    clone = BC.load(tmp_path / "bc.pt")
    obs = torch.randn(6, 4)
    assert torch.allclose(clone.policy_module.distribution(obs).loc, agent.policy_module.distribution(obs).loc)
    assert clone.n_updates == 5


def test_onpolicy_bc_loss_is_negative_log_likelihood_and_fit_is_noop():
    policy = ObsNormalizedPolicy(GaussianPolicy(1, 1, hidden=(), squash=False), 1, normalize=False)
    with torch.no_grad():
        policy.policy.net[0].weight.zero_()
        policy.policy.net[0].bias.zero_()
    # N(0, 1): -log p(a=1) = 0.5 * ln(2 pi) + 0.5 = 1.418939
    assert bc_loss(policy, torch.zeros(1, 1), torch.ones(1, 1)).item() == pytest.approx(1.418939, abs=1e-5)
    agent = BC(mdp_info(), small_policy(), seed=0)
    before = {k: v.clone() for k, v in agent.policy_module.state_dict().items()}
    agent.fit(fake_dataset())
    assert all(torch.equal(before[k], v) for k, v in agent.policy_module.state_dict().items())


# ---------------------------------------------------------------------------- dataset pairing
def test_onpolicy_bc_rejects_real_datasets_naming_alternatives():
    with pytest.raises(ValueError) as err:
        BC.check_dataset_type("real")
    for alternative in ("GAIL", "VAIL", "GAIfO"):
        assert alternative in str(err.value)
    agent = BC(mdp_info(), small_policy(), seed=0)
    with pytest.raises(ValueError, match="actions"):
        agent.set_expert(fake_expert(actions=False))
    BC.check_dataset_type("perfect")


def test_onpolicy_adversarial_agents_accept_all_dataset_types():
    for algo in (GAIL, VAIL, GAIfO):
        for kind in ("perfect", "preference", "real"):
            algo.check_dataset_type(kind)


def test_onpolicy_gail_state_only_on_real_and_clear_error_when_forced():
    agent = GAIL(mdp_info(), small_policy(), seed=0, **SMALL)
    assert agent.discriminator.input_kind == "sa"
    agent.set_expert(fake_expert(actions=False))
    assert agent.discriminator.input_kind == "s"  # picked automatically
    agent.fit(fake_dataset())
    forced = GAIL(mdp_info(), small_policy(), seed=0, use_actions=True, **SMALL)
    with pytest.raises(ValueError, match="no actions"):
        forced.set_expert(fake_expert(actions=False))
    assert GAIfO(mdp_info(), small_policy(), seed=0, **SMALL).discriminator.input_kind == "ss'"
    with pytest.raises(TypeError):
        GAIfO(mdp_info(), small_policy(), use_actions=True)


def test_onpolicy_fit_without_expert_fails_clearly():
    agent = GAIL(mdp_info(), small_policy(), seed=0, **SMALL)
    with pytest.raises(RuntimeError, match="set_expert"):
        agent.fit(fake_dataset())


# ---------------------------------------------------------------------------- configs
@pytest.mark.parametrize("name,algo", [("gail", GAIL), ("vail", VAIL), ("gaifo", GAIfO), ("bc", BC)])
def test_onpolicy_algo_configs_build_agents(name, algo):
    import pathlib

    import yaml
    path = pathlib.Path(__file__).resolve().parents[2] / "experiment_configs" / "algo" / f"{name}.yaml"
    cfg = yaml.safe_load(path.read_text())
    assert cfg["name"] == algo.name
    pol = GaussianPolicy(4, 1, hidden=cfg["policy"]["hidden"], squash=False,
                         init_log_std=cfg["policy"]["init_log_std"])
    agent = algo(mdp_info(), pol, seed=0, **cfg["params"])
    assert isinstance(agent.draw_action(np.zeros(4)), np.ndarray)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
@pytest.mark.parametrize("algo", [GAIL, VAIL, GAIfO])
def test_onpolicy_agents_fit_on_cuda(tmp_path, algo):
    kw = dict(SMALL, **({"z_dim": 3} if algo is VAIL else {}))
    agent = algo(mdp_info(), small_policy(), device="cuda", seed=0, **kw)
    agent.set_expert(fake_expert())
    agent.fit(fake_dataset())
    assert agent.draw_action(np.zeros(4)).shape == (1,)
    agent.save(tmp_path / "a.pt")
    assert algo.load(tmp_path / "a.pt", device="cpu").n_fits == 1


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_bc_pretrains_on_cuda_and_loads_on_cpu(tmp_path):
    agent = BC(mdp_info(), small_policy(), device="cuda", seed=0, batch_size=32)
    agent.set_expert(fake_expert())
    first = agent.pretrain(1)
    last = agent.pretrain(200)
    assert all(p.is_cuda for p in agent.policy_module.parameters())
    assert last < first  # the negative log-likelihood of the expert actions falls
    agent.save(tmp_path / "bc.pt")
    clone = BC.load(tmp_path / "bc.pt", device="cpu")
    obs = torch.randn(6, 4)
    assert torch.allclose(clone.policy_module.distribution(obs).loc,
                          agent.policy_module.distribution(obs.cuda()).loc.cpu(), atol=1e-5)


def test_onpolicy_loaded_state_keeps_the_configured_learning_rates():
    """As for the SAC-based agents: a state loaded into an agent built with other learning rates keeps them."""
    source = GAIL(mdp_info(), small_policy(), seed=0, **dict(SMALL, disc_lr=3e-4, vf_lr=3e-4))
    fork = GAIL(mdp_info(), small_policy(), seed=1, **dict(SMALL, disc_lr=1e-6, vf_lr=2e-6))
    fork.load_state_dict(source.state_dict())
    assert [g["lr"] for g in fork.disc_optimizer.param_groups] == [1e-6]
    assert [g["lr"] for g in fork.trpo.vf_optimizer.param_groups] == [2e-6]
