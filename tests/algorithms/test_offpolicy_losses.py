"""Unit tests of the off-policy IL losses and of the SAC / agent machinery, on hand-computed numbers."""
from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from mushroom_rl.core import MDPInfo
from mushroom_rl.utils.spaces import Box
from torch import nn

from loco_il.algorithms.common.ablations import Ablations
from loco_il.algorithms.common.agent_base import ALGORITHMS, get_algorithm
from loco_il.algorithms.iq_learn import IQLearn, iq_critic_loss
from loco_il.algorithms.lsiq import (LSIQ, LSIQfO, lsiq_bounds, lsiq_critic_loss, lsiq_fixed_expert_loss,
                                     lsiq_targets)
from loco_il.algorithms.sqil import SQIL, sqil_critic_loss, sqil_rewards
from loco_il.rl.networks import EnsembleQ, GaussianPolicy
from loco_il.rl.replay import TransitionBuffer
from loco_il.rl.sac import (SACCore, actor_loss, bc_regularized_actor_loss, conservative_penalty, polyak_update,
                            temperature_loss)

torch.set_num_threads(1)
T = lambda *x: torch.tensor(x, dtype=torch.float32)  # noqa: E731

OBS_DIM, ACT_DIM = 3, 2


# ---------------------------------------------------------------------- IQ-Learn
def test_iq_loss_hand_computed():
    # one expert sample (index 0), one agent sample whose s' is absorbing; gamma = 0.9, chi2 coef 0.5
    q, v, v_next, absorbing = T(2.0, 1.0), T(1.5, 0.5), T(1.0, 2.0), T(0.0, 1.0)
    # gamma V(s') masked: [0.9, 0]; r = q - that = [1.1, 1.0]
    # -E_E[r] = -1.1;  E_mix[V(s) - gamma V(s')] = mean(0.6, 0.5) = 0.55;  0.5 * mean(1.21, 1.0) = 0.5525
    loss, info = iq_critic_loss(q, v, v_next, absorbing, n_expert=1, gamma=0.9, chi2_coef=0.5)
    assert loss.item() == pytest.approx(-1.1 + 0.55 + 0.5525, abs=1e-6)
    assert info["reward_expert"].item() == pytest.approx(1.1)
    assert info["reward_policy"].item() == pytest.approx(1.0)
    # chi^2 on expert samples only: 0.5 * 1.21
    loss_e, _ = iq_critic_loss(q, v, v_next, absorbing, 1, 0.9, 0.5, regularize_policy=False)
    assert loss_e.item() == pytest.approx(-1.1 + 0.55 + 0.605, abs=1e-6)
    # "v0" value loss: (1 - gamma) V(s0) on the expert state only = 0.1 * 1.5; agent samples only in the chi^2 term
    loss_v0, _ = iq_critic_loss(q, v, v_next, absorbing, 1, 0.9, 0.5, value_loss="v0")
    assert loss_v0.item() == pytest.approx(-1.1 + 0.15 + 0.5525, abs=1e-6)
    with pytest.raises(ValueError, match="value_loss"):
        iq_critic_loss(q, v, v_next, absorbing, 1, 0.9, 0.5, value_loss="v1")
    # two identical heads: the head losses are summed
    loss2, _ = iq_critic_loss(torch.stack([q, q]), torch.stack([v, v]), torch.stack([v_next, v_next]),
                              absorbing, 1, 0.9, 0.5)
    assert loss2.item() == pytest.approx(2 * loss.item(), abs=1e-6)


def test_iq_loss_gradient_raises_expert_q():
    q = T(0.0, 0.0).requires_grad_()
    loss, _ = iq_critic_loss(q, T(0.0, 0.0), T(0.0, 0.0), T(0.0, 0.0), 1, 0.99)
    loss.backward()
    assert q.grad[0] < 0  # descending the loss increases Q on the expert sample


# ---------------------------------------------------------------------- LS-IQ
def test_lsiq_bounds():
    r_max, r_min, q_max, q_min = lsiq_bounds(reg_coef=0.5, mix=0.5, gamma=0.99)
    assert (r_max, r_min) == (pytest.approx(2.0), pytest.approx(-2.0))
    assert q_max == pytest.approx(1.0 / (0.5 * (1 - 0.99)))  # Q_max = 1 / (c (1 - gamma)) = 200
    assert q_min == pytest.approx(-q_max)
    r_max, r_min, _, _ = lsiq_bounds(reg_coef=1.0, mix=0.25, gamma=0.9)
    assert (r_max, r_min) == (pytest.approx(2.0), pytest.approx(-1.0 / 1.5))


def test_lsiq_target_clipping_and_absorbing():
    # gamma 0.9, c = a = 0.5: Q_max = 20, Q_min = -20; samples 0,1 expert, 2,3 agent; 1 and 3 absorbing
    v_next, absorbing = T(30.0, 5.0, -50.0, 3.0), T(0.0, 1.0, 0.0, 1.0)
    y = lsiq_targets(v_next, absorbing, n_expert=2, gamma=0.9)
    assert torch.allclose(y, T(0.9 * 20, 0.9 * 20, -0.9 * 20, -0.9 * 20))
    y0 = lsiq_targets(v_next, absorbing, n_expert=2, gamma=0.9, treat_absorbing=False)
    assert torch.allclose(y0, T(18.0, 0.0, -18.0, 0.0))
    # inside the bounds nothing is clipped
    y1 = lsiq_targets(T(1.0, -2.0), T(0.0, 0.0), n_expert=1, gamma=0.9)
    assert torch.allclose(y1, T(0.9, -1.8))


def test_lsiq_loss_hand_computed():
    q = T(19.0, 21.0, -19.0, -15.0)
    v_next, absorbing = T(30.0, 5.0, -50.0, 3.0), T(0.0, 1.0, 0.0, 1.0)
    # targets [18, 18, -18, -18] -> r = [1, 3, -1, 3]; r_max = 2, r_min = -2, weights c*a = c*(1-a) = 0.25
    # 0.25 * mean(1, 1) + 0.25 * mean(1, 25) = 0.25 + 3.25
    loss, info = lsiq_critic_loss(q, v_next, absorbing, n_expert=2, gamma=0.9)
    assert loss.item() == pytest.approx(3.5, abs=1e-5)
    assert info["reward_expert"].item() == pytest.approx(2.0)
    # IQ-Learn's V(s_A) = 0 instead: r = [1, 21, -1, -15] -> 0.25 * mean(1, 361) + 0.25 * mean(1, 169)
    loss0, _ = lsiq_critic_loss(q, v_next, absorbing, 2, 0.9, treat_absorbing=False)
    assert loss0.item() == pytest.approx(45.25 + 21.25, abs=1e-4)
    # optional value term E_pi[V(s) - Q(s, a)] = mean(-17 + 19, -14 + 15) = 1.5
    loss_v, _ = lsiq_critic_loss(q, v_next, absorbing, 2, 0.9, v_policy=T(-17.0, -14.0))
    assert loss_v.item() == pytest.approx(3.5 + 1.5, abs=1e-5)


def test_lsiq_fixed_expert_loss_hand_computed():
    # gamma 0.9, c = 0.5, mix 0.5 -> r_min = -2, Q_max = 20 = -Q_min; index 0 expert, index 1 agent
    q, v, v_next = T(18.0), T(5.0, -3.0), T(10.0, 30.0)  # Q only on the expert pair
    # expert: (18 - 20)^2 = 4; V regression on both states to -2 + 0.9 clip(V', -20, 20) = [7, 16]: mean(4, 361)
    loss, info = lsiq_fixed_expert_loss(q, v, v_next, T(0.0, 0.0), 1, 0.9)
    assert loss.item() == pytest.approx(4 + 182.5)
    # logged implicit rewards: expert 18 - 0.9 * 10 = 9; agent V(s) - 0.9 clip(30) = -3 - 18 = -21
    assert info["reward_expert"].item() == pytest.approx(9.0) and info["reward_policy"].item() == pytest.approx(-21.0)
    # absorbing agent transition: target r_min / (1 - gamma) = -20 -> (-3 + 20)^2 = 289
    loss_abs, _ = lsiq_fixed_expert_loss(q, v, v_next, T(0.0, 1.0), 1, 0.9)
    assert loss_abs.item() == pytest.approx(4 + (4 + 289) / 2)
    # without the treatment (the released runs): V(s_A) = 0 -> target -2 -> (-3 + 2)^2 = 1
    loss_0, _ = lsiq_fixed_expert_loss(q, v, v_next, T(0.0, 1.0), 1, 0.9, treat_absorbing=False)
    assert loss_0.item() == pytest.approx(4 + (4 + 1) / 2)
    with pytest.raises(ValueError, match="objective"):
        _agent(LSIQ, objective="sqil_like")


def test_lsiq_loss_minimum_is_at_reward_bounds():
    q = T(0.0, 0.0).requires_grad_()
    opt = torch.optim.SGD([q], lr=1.0)
    for _ in range(200):
        loss, _ = lsiq_critic_loss(q, T(0.0, 0.0), T(0.0, 0.0), 1, 0.9)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert torch.allclose(q.detach(), T(2.0, -2.0), atol=1e-4)  # Q = r_max / r_min when V(s') = 0


# ---------------------------------------------------------------------- SQIL
def test_sqil_rewards_and_loss():
    assert torch.equal(sqil_rewards(2, 3), T(1.0, 1.0, 0.0, 0.0, 0.0))
    # targets r + gamma (1 - absorbing) V(s') = [1 + 0.5 * 2, 0] = [2, 0]; errors [-1, 0]
    loss, _ = sqil_critic_loss(T(1.0, 0.0), T(1.0, 0.0), T(2.0, 5.0), T(0.0, 1.0), gamma=0.5)
    assert loss.item() == pytest.approx(0.5)


# ---------------------------------------------------------------------- SAC pieces
def test_actor_loss_hand_computed():
    assert actor_loss(torch.tensor(0.5), T(1.0, -1.0), T(2.0, 3.0)).item() == pytest.approx(-2.5)


@pytest.mark.parametrize("log_prob, alpha_goes_up", [(3.0, True), (-3.0, False)])
def test_temperature_update_sign(log_prob, alpha_goes_up):
    # target entropy -1: log pi = 3 (entropy -3, below the target) must raise alpha,
    # log pi = -3 (entropy 3, above it) must lower it
    log_alpha = torch.zeros((), requires_grad=True)
    opt = torch.optim.SGD([log_alpha], lr=0.1)
    loss = temperature_loss(log_alpha, torch.full((4,), log_prob), target_entropy=-1.0)
    opt.zero_grad()
    loss.backward()
    opt.step()
    assert (log_alpha.item() > 0) == alpha_goes_up


def test_target_soft_value_with_and_without_the_entropy_term():
    torch.manual_seed(0)
    core = SACCore(GaussianPolicy(3, 2, (8,)), 3, 2, (8,), init_alpha=0.7)
    next_obs = torch.randn(5, 3)
    torch.manual_seed(1)
    action, logp = core.policy.sample(next_obs)
    q_min = torch.minimum(*core.critic_target(next_obs, action)).detach()
    for with_entropy, expected in [(True, q_min - 0.7 * logp.detach()), (False, q_min)]:
        torch.manual_seed(1)                           # the same sampled a' ~ pi(.|s')
        torch.testing.assert_close(core.target_soft_value(next_obs, with_entropy=with_entropy), expected)


def test_polyak_update():
    src, tgt = nn.Linear(2, 2), nn.Linear(2, 2)
    before = [p.detach().clone() for p in tgt.parameters()]
    polyak_update(tgt, src, tau=0.1)
    for b, s, t in zip(before, src.parameters(), tgt.parameters()):
        assert torch.allclose(t, 0.9 * b + 0.1 * s)


def test_conservative_penalty_hand_computed():
    # one head, K = 2 random actions, N = 2 states
    # state 0: random Q 0, 0 -> log mean exp = 0, stored Q 1 -> -1
    # state 1: random Q log 3, 0 -> log((3 + 1) / 2) = log 2, stored Q 0 -> log 2
    q_random = torch.tensor([[[0.0, float(np.log(3.0))], [0.0, 0.0]]])
    q_data = T(1.0, 0.0).unsqueeze(0).requires_grad_()
    penalty = conservative_penalty(q_random, q_data)
    assert penalty.item() == pytest.approx((-1.0 + np.log(2.0)) / 2, abs=1e-6)
    penalty.backward()
    assert torch.allclose(q_data.grad, T(-0.5, -0.5).unsqueeze(0))   # descending it raises the stored action's Q
    # two identical heads: summed; the random actions' weights are their softmax (state 1: 3/4 and 1/4)
    q_random2 = torch.cat([q_random, q_random]).requires_grad_()
    penalty2 = conservative_penalty(q_random2, torch.cat([q_data, q_data]).detach())
    assert penalty2.item() == pytest.approx(2 * penalty.item(), abs=1e-6)
    penalty2.backward()
    assert torch.allclose(q_random2.grad[0, :, 1], T(0.375, 0.125))
    # hinged: state 0's negative term counts 0 and passes no gradient
    q_data.grad = None
    hinged = conservative_penalty(q_random, q_data, hinge=True)
    assert hinged.item() == pytest.approx(np.log(2.0) / 2, abs=1e-6)
    hinged.backward()
    assert torch.allclose(q_data.grad, T(0.0, -0.5).unsqueeze(0))


def test_bc_regularized_actor_loss_hand_computed():
    # lambda = 2.5 / mean(|-4|, |6|) = 0.5; BC: mean over 2 states of the summed squared error: (0.25 + 1) / 2
    sac_loss, q = torch.tensor(3.0), T(-4.0, 6.0)
    mean_action, expert_action = T(0.5, 0.0, 0.0, 1.0).view(2, 2), torch.zeros(2, 2)
    loss = bc_regularized_actor_loss(sac_loss, q, mean_action.requires_grad_(), expert_action, bc_alpha=2.5)
    assert loss.item() == pytest.approx(0.5 * 3.0 + 0.625)
    loss.backward()
    assert torch.allclose(mean_action.grad, T(0.5, 0.0, 0.0, 1.0).view(2, 2))   # d/dm mean_i |m_i - a_i|^2


# ---------------------------------------------------------------------- agents
def _mdp_info():
    return MDPInfo(Box(-np.ones(OBS_DIM), np.ones(OBS_DIM)), Box(-np.ones(ACT_DIM), np.ones(ACT_DIM)), 0.99, 100)


def _expert(n=50, seed=0, with_actions=True):
    rng = np.random.default_rng(seed)
    obs = rng.normal(size=(n, OBS_DIM))
    return SimpleNamespace(obs=obs, next_obs=obs + 0.1, actions=rng.uniform(-1, 1, (n, ACT_DIM)) if with_actions else None,
                           absorbing=np.zeros(n, bool), last=np.r_[np.zeros(n - 1, bool), True])


def _dataset(n=64, seed=1):
    rng = np.random.default_rng(seed)
    return [(rng.normal(size=OBS_DIM), rng.uniform(-1, 1, ACT_DIM), 0.0, rng.normal(size=OBS_DIM),
             bool(i % 10 == 9), bool(i % 10 == 9)) for i in range(n)]


def _agent(cls, seed=0, **kw):
    torch.manual_seed(seed)
    agent = cls(_mdp_info(), GaussianPolicy(OBS_DIM, ACT_DIM, (16,)), critic_hidden=(16,), batch_size=8,
                expert_batch_size=8, initial_replay_size=16, replay_capacity=1000, seed=seed, **kw)
    agent.set_expert(_expert(with_actions=cls is not LSIQfO))
    return agent


def test_registry_and_dataset_types():
    assert {"iqlearn", "lsiq", "lsiqfo", "sqil"} <= set(ALGORITHMS)
    assert get_algorithm("LSIQ") is LSIQ
    with pytest.raises(ValueError, match="LSIQ-fO"):
        IQLearn.check_dataset_type("real")
    for cls in (SQIL, LSIQ):
        with pytest.raises(ValueError, match="LSIQ-fO"):
            cls.check_dataset_type("real")
    for cls in (IQLearn, LSIQ, LSIQfO, SQIL):
        cls.check_dataset_type("perfect")
        cls.check_dataset_type("preference")
    LSIQfO.check_dataset_type("real")
    with pytest.raises(ValueError, match="unknown"):
        SQIL.check_dataset_type("mocap")


def test_expert_without_actions_rejected_unless_state_only():
    with pytest.raises(ValueError, match="actions"):
        _agent(IQLearn).set_expert(_expert(with_actions=False))
    _agent(LSIQfO).set_expert(_expert(with_actions=False))


def _critic_loss_on_small_batches(agent, next_obs_value: float):
    """The agent's critic loss on 5 expert + 7 replay samples (4 replay transitions); the torch seed is
    reset afterwards, so that a hand computation draws the same policy noise."""
    agent.replay.add(np.zeros((4, OBS_DIM)), np.full((4, OBS_DIM), next_obs_value), np.zeros(4),
                     np.zeros((4, ACT_DIM)))
    expert = agent.expert_buffer.sample(5, agent.rng)
    policy = agent.replay.sample(7, agent.rng)
    torch.manual_seed(3)
    loss, _ = agent.critic_loss(expert, policy)
    torch.manual_seed(3)
    return expert, policy, loss


def test_sqil_agent_relabels_expert_1_agent_0():
    agent = _agent(SQIL)
    expert, policy, loss = _critic_loss_on_small_batches(agent, 0.0)
    # recompute by hand with the same policy noise: rewards 1 for the 5 expert, 0 for the 7 agent samples
    nxt = torch.cat([expert["next_obs"], policy["next_obs"]])
    a, logp = agent.policy_module.sample(nxt)
    t1, t2 = agent.sac.critic_target(nxt, a)
    y = torch.cat([torch.ones(5), torch.zeros(7)]) + 0.99 * (torch.minimum(t1, t2) - agent.sac.alpha * logp)
    q1, q2 = agent.sac.critic(torch.cat([expert["obs"], policy["obs"]]), torch.cat([expert["actions"], policy["actions"]]))
    assert loss.item() == pytest.approx(((q1 - y) ** 2).mean().item() + ((q2 - y) ** 2).mean().item(), rel=1e-5)


def test_sqil_q_bound_flags_a_diverged_critic():
    agent = _agent(SQIL, init_alpha=0.01, learn_alpha=False)
    bound = (1.0 + 0.01 * ACT_DIM * math.log(2.0)) / (1.0 - 0.99)
    assert agent.q_upper_bound() == pytest.approx(bound)
    assert agent.critic_divergence(torch.tensor(9.9 * bound)) is None
    note = agent.critic_divergence(torch.tensor(11.0 * bound))
    assert note.startswith("the critic diverged") and "SQIL" in note and f"{bound:.4g}" in note
    assert agent.critic_divergence(float("nan")) is not None
    # a learner whose method does not bound Q is never flagged
    assert _agent(IQLearn).critic_divergence(1e12) is None


def test_runner_warns_once_when_the_critic_diverges():
    from loco_il.experiment.runner import Runner
    runner = Runner.__new__(Runner)          # only the pieces the check reads
    runner.agent, runner.counters, lines = _agent(SQIL), {"critic_diverged_at": None}, []
    runner.logger = SimpleNamespace(write=lines.append)
    bound = runner.agent.q_upper_bound()
    for step, q in [(10, 2.0 * bound), (20, 50.0 * bound), (30, 60.0 * bound)]:
        runner._note_critic_divergence({"step": step, "fit/q_mean": torch.tensor(q)})
    runner._note_critic_divergence({"step": 40})   # rows without a mean Q (e.g. BC) are left alone
    assert runner.counters["critic_diverged_at"] == 20
    assert len(lines) == 1 and lines[0].startswith("[loco_il] warning at step 20: the critic diverged")


def test_iqlearn_agent_v0_loss_reads_v_on_expert_states_and_target_next_value():
    agent = _agent(IQLearn)  # defaults: value_loss="v0", use_target=True
    expert, policy, loss = _critic_loss_on_small_batches(agent, 1.0)
    # by hand, same policy noise: one draw for [expert states; all next states]
    obs = torch.cat([expert["obs"], policy["obs"]])
    nxt = torch.cat([expert["next_obs"], policy["next_obs"]])
    a, logp = agent.policy_module.sample(torch.cat([expert["obs"], nxt]))
    alpha = agent.sac.alpha
    t1, t2 = agent.sac.critic_target(nxt, a[5:])
    v_next = torch.minimum(t1, t2) - alpha * logp[5:]
    q = agent.sac.critic(obs, torch.cat([expert["actions"], policy["actions"]]))
    v = agent.sac.critic(expert["obs"], a[:5])
    expected = sum(iq_critic_loss(qi, vi - alpha * logp[:5], v_next, torch.zeros(12), 5, 0.99, 0.5,
                                  value_loss="v0")[0] for qi, vi in zip(q, v))
    assert loss.item() == pytest.approx(expected.item(), rel=1e-5)
    with pytest.raises(ValueError, match="value_loss"):
        _agent(IQLearn, value_loss="value0")


@pytest.mark.parametrize("n_critics", [1, 2])   # 1: LS-IQ's default
def test_lsiq_agent_mixture_loss_reads_v_on_agent_states_only(n_critics):
    agent = _agent(LSIQ, objective="mixture", n_critics=n_critics)  # value_term=True by default
    expert, policy, loss = _critic_loss_on_small_batches(agent, 1.0)
    # by hand, same policy noise: one draw for [agent states; all next states]
    nxt = torch.cat([expert["next_obs"], policy["next_obs"]])
    a, logp = agent.policy_module.sample(torch.cat([policy["obs"], nxt]))
    alpha = agent.sac.alpha
    v_next = agent.sac.critic_target(nxt, a[7:]).amin(0) - alpha * logp[7:]   # the minimum over the heads
    q = agent.sac.critic(torch.cat([expert["obs"], policy["obs"]]), torch.cat([expert["actions"], policy["actions"]]))
    v = agent.sac.critic(policy["obs"], a[:7])
    assert len(q) == len(v) == n_critics
    absorbing = torch.cat([expert["absorbing"], policy["absorbing"]])
    expected = sum(lsiq_critic_loss(qi, v_next, absorbing, 5, 0.99, v_policy=vi - alpha * logp[:7])[0]
                   for qi, vi in zip(q, v))
    assert loss.item() == pytest.approx(expected.item(), rel=1e-5)
    with pytest.raises(ValueError, match="v_on"):
        agent.critic_values(expert, policy, v_on="agent")


@pytest.mark.parametrize("n_critics, gamma", [(2, None), (1, None), (1, 0.995)])  # None: the MDPInfo's 0.99
def test_lsiq_agent_default_fixed_expert_loss_reads_v_on_all_states(n_critics, gamma):
    agent = _agent(LSIQ, n_critics=n_critics, gamma=gamma)  # default objective="fixed_expert"
    assert agent.gamma == (0.99 if gamma is None else gamma)
    assert len(list(agent.sac.critic.children())) == n_critics
    expert, policy, loss = _critic_loss_on_small_batches(agent, 1.0)
    obs = torch.cat([expert["obs"], policy["obs"]])
    nxt = torch.cat([expert["next_obs"], policy["next_obs"]])
    a, logp = agent.policy_module.sample(torch.cat([obs, nxt]))
    alpha = agent.sac.alpha
    heads = [agent.sac.critic_target.q1] + ([agent.sac.critic_target.q2] if n_critics == 2 else [])
    t = [h(torch.cat([nxt, a[12:]], -1)).squeeze(-1) for h in heads]
    v_next = (torch.minimum(*t) if n_critics == 2 else t[0]) - alpha * logp[12:]
    q = agent.sac.critic(expert["obs"], expert["actions"])
    v = agent.sac.critic(obs, a[:12])
    assert q.shape == (n_critics, 5) and v.shape == (n_critics, 12)
    absorbing = torch.cat([expert["absorbing"], policy["absorbing"]])
    expected = sum(lsiq_fixed_expert_loss(qi, vi - alpha * logp[:12], v_next, absorbing, 5, agent.gamma)[0]
                   for qi, vi in zip(q, v))
    assert loss.item() == pytest.approx(expected.item(), rel=1e-5)


@pytest.mark.parametrize("gamma", [0.0, 1.0, 1.5])
def test_gamma_outside_the_unit_interval_rejected(gamma):
    with pytest.raises(ValueError, match="gamma"):
        _agent(SQIL, gamma=gamma)


# (class, options, rows of [expert; agent] states at which the critic reads V(s)), batches of 8 + 8
SHARED_FORWARD_CASES = [(IQLearn, {}, 8), (IQLearn, {"value_loss": "value"}, 16),
                        (LSIQ, {}, 16), (LSIQ, {"objective": "mixture"}, 8), (LSIQfO, {}, 16), (SQIL, {}, 0)]


def _policy_rows_per_update(agent, n_updates=3):
    """Rows run through the policy network per update, counted by a forward hook."""
    rows = []
    hook = agent.policy_module.net.register_forward_hook(lambda mod, inp, out: rows.append(len(inp[0])))
    try:
        for _ in range(n_updates):
            agent.update()
    finally:
        hook.remove()
    return sum(rows) / n_updates


@pytest.mark.parametrize("cls, kw, v_rows", SHARED_FORWARD_CASES)
def test_update_runs_the_policy_once_per_state_and_matches_the_unshared_update(cls, kw, v_rows):
    """The critic's V(s) terms sample from the policy forward the actor step takes anyway (at the 16 states of the
    batch), so an update runs the policy on 16 + 16 rows (states, next states) instead of 16 + v_rows + 16; and
    the update is the same as when the critic runs its own forward (the code before the forward was shared)."""
    shared, unshared = _agent(cls, **kw), _agent(cls, **kw)
    loss_of = cls.critic_loss
    unshared.critic_loss = lambda expert, policy, pi_obs=None: loss_of(unshared, expert, policy)
    rows = {}
    for agent in (shared, unshared):
        torch.manual_seed(1)  # the same policy noise for both
        agent.fit(_dataset(n=20))  # 16 for the initial replay, then 4 updates
        rows[agent] = _policy_rows_per_update(agent)
    assert rows[shared] == 32 and rows[unshared] == 32 + v_rows
    for a, b in ((shared.policy_module, unshared.policy_module), (shared.sac.critic, unshared.sac.critic)):
        for (name, p), q in zip(a.named_parameters(), b.parameters()):
            torch.testing.assert_close(p, q, rtol=1e-6, atol=1e-7, msg=f"{cls.__name__} {kw}: {name} differs")
    # the actor's states are the agent rows only, or the actor skips an update: no forward to share
    agent = _agent(cls, **kw, actor_on_expert_states=False)
    agent.fit(_dataset(n=16))
    assert _policy_rows_per_update(agent) == 16 + v_rows + 8
    agent = _agent(cls, **kw, actor_delay=2)
    agent.fit(_dataset(n=16))  # 16 updates: the next one takes the actor step, the one after does not
    assert [_policy_rows_per_update(agent, 1) for _ in range(2)] == [32, 16 + v_rows]


def test_single_critic_actor_step_follows_its_only_head():
    """n_critics=1: the actor's loss is alpha log pi - Q of that critic (no minimum over heads); updates run."""
    agent = _agent(LSIQ, n_critics=1)
    obs = torch.randn(6, OBS_DIM)
    torch.manual_seed(4)
    with torch.no_grad():
        a, logp = agent.policy_module.sample(obs)
        expected = (agent.sac.alpha * logp - agent.sac.critic.q1(torch.cat([obs, a], -1)).squeeze(-1)).mean()
    torch.manual_seed(4)                       # the same policy noise inside actor_step
    info = agent.sac.actor_step(obs)
    assert info["actor_loss"].item() == pytest.approx(expected.item(), rel=1e-6)
    agent.fit(_dataset(n=20))                  # >= initial_replay_size (16): one update per new transition
    assert agent.n_updates == 20
    assert {k.split(".")[0] for k in agent.sac.critic.state_dict()} == {"q1"}
    with pytest.raises(ValueError, match="n_heads"):
        _agent(LSIQ, n_critics=0)


def test_layer_norm_critic_bounds_extrapolation():
    """critic_layer_norm: LayerNorm between each hidden Linear and its ReLU. With zero first-layer biases the
    normalized features, and so Q, do not grow when (s, a) is scaled up; a plain critic's Q grows with it."""
    torch.manual_seed(0)
    plain, normed = EnsembleQ(OBS_DIM, ACT_DIM, (16, 16)), EnsembleQ(OBS_DIM, ACT_DIM, (16, 16), layer_norm=True)
    assert [type(m) for m in normed.q1] == [nn.Linear, nn.LayerNorm, nn.ReLU] * 2 + [nn.Linear]
    assert [type(m) for m in plain.q1] == [nn.Linear, nn.ReLU] * 2 + [nn.Linear]
    for net in (plain, normed):
        for head in net.children():
            nn.init.zeros_(head[0].bias)
    obs, act = torch.randn(32, OBS_DIM), torch.rand(32, ACT_DIM) * 2 - 1
    with torch.no_grad():
        q_plain, q_plain_far = plain(obs, act), plain(100 * obs, 100 * act)
        q_normed, q_normed_far = normed(obs, act), normed(100 * obs, 100 * act)
    torch.testing.assert_close(q_normed_far, q_normed, rtol=1e-3, atol=1e-3)
    assert q_plain_far.abs().mean() > 20 * q_plain.abs().mean()


@pytest.mark.parametrize("cls", [IQLearn, LSIQ, SQIL])
def test_layer_norm_critic_trains_and_survives_save_and_load(cls, tmp_path):
    agent = _agent(cls, ablations=Ablations(critic_layer_norm=True))
    ln_before = agent.sac.critic.q1[1].weight.clone()
    agent.fit(_dataset())                      # 64 transitions >= initial_replay_size: one update each
    assert agent.n_updates == 64
    assert not torch.equal(agent.sac.critic.q1[1].weight, ln_before)   # the LayerNorm gains are trained
    agent.save(tmp_path / "agent.pt")
    restored = cls.load(tmp_path / "agent.pt")
    assert any(isinstance(m, nn.LayerNorm) for m in restored.sac.critic_target.q1)
    obs, act = torch.randn(5, OBS_DIM), torch.rand(5, ACT_DIM)
    with torch.no_grad():
        torch.testing.assert_close(restored.sac.critic(obs, act), agent.sac.critic(obs, act), rtol=0, atol=0)


def test_replay_ring_buffer_keeps_newest():
    buf = TransitionBuffer(3, 1, 1)
    for i in range(5):
        buf.add(np.array([[i]]), np.array([[i + 1]]), np.array([0.0]), np.array([[-i]]))
    assert len(buf) == 3
    assert sorted(buf.obs[:, 0].tolist()) == [2.0, 3.0, 4.0]
    batch = buf.sample(100, np.random.default_rng(0))
    assert torch.equal(batch["next_obs"], batch["obs"] + 1) and torch.equal(batch["actions"], -batch["obs"])


@pytest.mark.parametrize("cls", [IQLearn, LSIQ, LSIQfO, SQIL])
def test_state_dict_round_trip(cls, tmp_path):
    agent = _agent(cls)
    agent.fit(_dataset()[:10])                 # replay below initial_replay_size (16): no update
    assert agent.n_updates == 0 and agent.n_transitions == 10
    agent.fit(_dataset(seed=4))                # 64 more transitions: one update each
    assert agent.n_updates == 64
    path = tmp_path / "agent.pt"
    agent.save(path)
    replay_state = agent.replay.state_dict()   # the replay memory is not part of the checkpoint
    probe = np.random.default_rng(5).normal(size=(6, OBS_DIM))
    acts_before = [agent.draw_action(s) for s in probe]
    params_before = {k: v.clone() for k, v in agent.sac.critic.state_dict().items()}

    restored = cls.load(path)                  # a new agent built from the file
    assert type(restored) is cls and restored.n_updates == agent.n_updates
    np.testing.assert_array_equal([restored.draw_action(s) for s in probe], acts_before)
    for k, v in restored.sac.critic.state_dict().items():
        assert torch.equal(v, params_before[k])
    assert restored.sac.log_alpha.item() == agent.sac.log_alpha.item()

    # both continue identically (optimizer moments, counters, RNG streams restored)
    restored.set_expert(_expert(with_actions=cls is not LSIQfO))
    restored.replay.load_state_dict(replay_state)
    global_rng = torch.get_rng_state()
    agent.fit(_dataset(seed=2))
    torch.set_rng_state(global_rng)            # the global torch RNG is per process; emulate a fresh one
    restored.fit(_dataset(seed=2))
    for (k, v), v2 in zip(agent.sac.critic.state_dict().items(), restored.sac.critic.state_dict().values()):
        assert torch.equal(v, v2), k
    assert any(not torch.equal(v, params_before[k]) for k, v in agent.sac.critic.state_dict().items())

    agent.load(path)                           # restore in place
    for k, v in agent.sac.critic.state_dict().items():
        assert torch.equal(v, params_before[k])
    for p, q in zip(agent.policy_module.parameters(), restored.policy_module.parameters()):
        assert p.shape == q.shape
    np.testing.assert_array_equal([agent.draw_action(s) for s in probe], acts_before)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
@pytest.mark.parametrize("cls", [IQLearn, LSIQ, LSIQfO, SQIL])
def test_offpolicy_agents_train_on_cuda_resume_there_and_load_on_cpu(cls, tmp_path):
    agent = _agent(cls, device="cuda")
    agent.fit(_dataset(n=40))                  # past initial_replay_size (16): one update per new transition
    assert agent.n_updates == 40
    assert agent.replay.obs.is_cuda and all(p.is_cuda for p in agent.sac.critic.parameters())
    assert all(torch.isfinite(p).all() for p in agent.sac.critic.parameters())
    path = tmp_path / "agent.pt"
    agent.save(path)
    probe = np.random.default_rng(5).normal(size=(6, OBS_DIM))

    on_cpu = cls.load(path, device="cpu")      # a GPU run's checkpoint read on a CPU machine
    assert on_cpu.device.type == "cpu" and not any(p.is_cuda for p in on_cpu.sac.critic.parameters())
    agent.deterministic = on_cpu.deterministic = True
    np.testing.assert_allclose([on_cpu.draw_action(s) for s in probe], [agent.draw_action(s) for s in probe],
                               atol=1e-5)
    agent.deterministic = False

    # resumed on the GPU, it continues as the original does (the CUDA RNG state is in the checkpoint)
    resumed = cls.load(path, device="cuda")
    resumed.set_expert(_expert(with_actions=cls is not LSIQfO))
    resumed.replay.load_state_dict(agent.replay.state_dict())
    rng_state = torch.get_rng_state(), torch.cuda.get_rng_state_all()
    agent.fit(_dataset(seed=2, n=20))
    torch.set_rng_state(rng_state[0])          # emulate a fresh process for the resumed agent
    torch.cuda.set_rng_state_all(rng_state[1])
    resumed.fit(_dataset(seed=2, n=20))
    for (k, v), v2 in zip(agent.sac.critic.state_dict().items(), resumed.sac.critic.state_dict().values()):
        torch.testing.assert_close(v, v2, rtol=0, atol=1e-6, msg=k)


def _params_close(a: nn.Module, b: nn.Module, atol: float) -> None:
    for (k, v), v2 in zip(a.state_dict().items(), b.state_dict().values()):
        torch.testing.assert_close(v, v2, rtol=0, atol=atol, msg=k)


def _graphed_and_eager_agree(cls, **kw):
    """40 updates eager and 40 with cuda_graph=True (3 eager, then the captured one replayed) from the same RNG
    state leave the same parameters and critic loss; returns the graphed agent."""
    eager, graphed = _agent(cls, device="cuda", **kw), _agent(cls, device="cuda", cuda_graph=True, **kw)
    rng_state = torch.get_rng_state(), torch.cuda.get_rng_state_all()
    eager.fit(_dataset(n=40))
    torch.set_rng_state(rng_state[0])
    torch.cuda.set_rng_state_all(rng_state[1])
    graphed.fit(_dataset(n=40))
    assert graphed._graphed_step.graph is not None and graphed.n_updates == eager.n_updates == 40
    for net in ("critic", "critic_target"):
        _params_close(getattr(eager.sac, net), getattr(graphed.sac, net), atol=1e-5)
    _params_close(eager.policy_module, graphed.policy_module, atol=1e-5)
    torch.testing.assert_close(eager.last_info["critic_loss"], graphed.last_info["critic_loss"], rtol=1e-4, atol=1e-5)
    return graphed


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
@pytest.mark.parametrize("cls", [IQLearn, LSIQ, LSIQfO, SQIL])
def test_cuda_graph_updates_compute_what_the_eager_updates_compute(cls, tmp_path):
    """cuda_graph=True: 3 eager updates, then the captured one replayed; same parameters as eager updates from the
    same RNG state, also after a checkpoint (the optimizers' state is replaced on load: captured again)."""
    graphed = _graphed_and_eager_agree(cls)

    path = tmp_path / "graphed.pt"
    graphed.save(path)
    resumed = cls.load(path)
    assert resumed.cuda_graph and resumed._graphed_step.graph is None
    resumed.set_expert(_expert(with_actions=cls is not LSIQfO))
    resumed.replay.load_state_dict(graphed.replay.state_dict())
    rng_state = torch.get_rng_state(), torch.cuda.get_rng_state_all()
    graphed.fit(_dataset(seed=2, n=20))
    torch.set_rng_state(rng_state[0])
    torch.cuda.set_rng_state_all(rng_state[1])
    resumed.fit(_dataset(seed=2, n=20))
    assert resumed._graphed_step.graph is not None
    _params_close(graphed.sac.critic, resumed.sac.critic, atol=1e-5)
    assert not cls.load(path, device="cpu").cuda_graph      # read on the CPU: the same updates, eager


LAYER_NORM = Ablations(critic_layer_norm=True)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
@pytest.mark.parametrize("cls, kw", [
    (LSIQ, {"objective": "mixture", "n_critics": 2, "ablations": LAYER_NORM}),  # the README's Hopper setting
    (LSIQ, {"ablations": LAYER_NORM}),
    (IQLearn, {"ablations": LAYER_NORM}),
    (LSIQfO, {"ablations": LAYER_NORM, "n_critics": 2}),
    (SQIL, {"ablations": LAYER_NORM}),
])
def test_cuda_graph_matches_eager_with_the_layer_norm_and_twin_critics(cls, kw):
    graphed = _graphed_and_eager_agree(cls, **kw)
    norms = [m for m in graphed.sac.critic.modules() if isinstance(m, nn.LayerNorm)]
    assert norms and all(torch.isfinite(m.weight).all() for m in norms)   # the option really built a LayerNorm critic


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_cuda_graph_needs_actor_delay_1():
    with pytest.raises(ValueError, match="actor_delay=1"):
        _agent(SQIL, device="cuda", cuda_graph=True, actor_delay=2)


def test_cuda_graph_rejected_off_cuda_and_dropped_when_a_graphed_checkpoint_loads_on_the_cpu(tmp_path):
    with pytest.raises(ValueError, match="needs device=cuda"):
        _agent(LSIQ, cuda_graph=True)
    agent = _agent(LSIQ)
    agent.save(tmp_path / "a.pt")
    ckpt = torch.load(tmp_path / "a.pt", weights_only=False)
    ckpt["init_kwargs"]["cuda_graph"] = True                   # as a device=cuda cuda_graph=True run writes it
    torch.save(ckpt, tmp_path / "graphed.pt")
    loaded = LSIQ.load(tmp_path / "graphed.pt", device="cpu")
    assert not loaded.cuda_graph and loaded._graphed_step is None
    _params_close(agent.sac.critic, loaded.sac.critic, atol=0)


def test_deterministic_action_is_squashed_mean():
    agent = _agent(SQIL)
    agent.deterministic = True
    s = np.ones(OBS_DIM)
    a1, a2 = agent.draw_action(s), agent.draw_action(s)
    np.testing.assert_array_equal(a1, a2)
    expected = agent.policy_module.deterministic(torch.ones(1, OBS_DIM, dtype=torch.float32))[0].detach().numpy()
    np.testing.assert_allclose(a1, expected, rtol=1e-6)
    agent.deterministic = False
    assert np.all(np.abs(agent.draw_action(s)) <= 1.0)


def test_log_std_bounds_clamp_the_squashed_policy_in_torch_and_numpy():
    from loco_il.algorithms.factory import build_policy
    policy = build_policy(LSIQ, OBS_DIM, ACT_DIM, {"hidden": [16], "log_std_bounds": [-5, 2]})
    assert ACT_DIM == 2
    with torch.no_grad():                      # raw log-std outputs -9 and 7 for every input: outside [-5, 2]
        last = policy.net[-1]
        last.weight.zero_()
        last.bias[ACT_DIM:] = torch.tensor([-9.0, 7.0])
    obs = torch.ones(3, OBS_DIM)
    _, log_std = policy._mean_log_std(obs)
    expected = torch.tensor([-5.0, 2.0])
    assert torch.equal(log_std, expected.expand(3, ACT_DIM))
    mean_log_std, _ = policy.numpy_mean_log_std()
    np.testing.assert_array_equal(mean_log_std(np.ones(OBS_DIM, np.float32))[1], expected.numpy())
    default = build_policy(LSIQ, OBS_DIM, ACT_DIM, {"hidden": [16]})
    assert (default.log_std_min, default.log_std_max) == (-20.0, 2.0)


def test_log_std_bounds_rejected_where_they_cannot_apply():
    from loco_il.algorithms.factory import build_policy
    from loco_il.algorithms.gail import GAIL
    with pytest.raises(ValueError, match="free .unclamped. log-std"):
        build_policy(GAIL, OBS_DIM, ACT_DIM, {"log_std_bounds": [-5, 2]})
    with pytest.raises(ValueError, match=r"must be \[min, max\]"):
        build_policy(LSIQ, OBS_DIM, ACT_DIM, {"log_std_bounds": [-5]})
    with pytest.raises(ValueError, match="min < max"):
        build_policy(LSIQ, OBS_DIM, ACT_DIM, {"log_std_bounds": [2, -5]})


def test_runs_checkpointed_before_log_std_bounds_existed_still_resume():
    from loco_il.experiment.checkpoint import config_differences
    old = {"algo": {"name": "lsiq", "policy": {"hidden": [256, 256]}}}
    new = {"algo": {"name": "lsiq", "policy": {"hidden": [256, 256], "log_std_bounds": [-20.0, 2.0]}}}
    assert config_differences(old, new) == []
    new["algo"]["policy"]["log_std_bounds"] = [-5.0, 2.0]
    assert config_differences(old, new) == ["algo.policy.log_std_bounds: [-20.0, 2.0] -> [-5.0, 2.0]"]


# ---------------------------------------------------------------------- the actor's moving average (actor_ema)
def _params(module: nn.Module) -> list[torch.Tensor]:
    return [p.detach().clone() for p in module.parameters()]


def test_actor_average_follows_its_rate_and_leaves_training_unchanged():
    agents = []
    for kw in ({}, {"actor_ema": 0.1}):   # one after the other: the updates draw from torch's global RNG
        agents.append(_agent(LSIQ, seed=4, **kw))
        agents[-1].fit(_dataset(n=32))     # 16 updates once the replay holds 16 transitions
    plain, averaged = agents
    assert plain.policy_ema is None
    assert averaged.n_updates == plain.n_updates > 0
    for a, b in zip(_params(plain.policy_module), _params(averaged.policy_module)):
        assert torch.equal(a, b)               # the average never acts or draws random numbers in training
    before = _params(averaged.policy_ema)
    averaged.update()
    live = _params(averaged.policy_module)
    for ema, old, new in zip(_params(averaged.policy_ema), before, live):
        torch.testing.assert_close(ema, old + 0.1 * (new - old))
    assert any(not torch.equal(e, p) for e, p in zip(_params(averaged.policy_ema), live))


def test_averaged_actor_acts_inside_the_block_and_restores_the_live_actor():
    agent = _agent(LSIQ, actor_ema=0.05)
    agent.fit(_dataset(n=48))
    agent.deterministic = True
    obs = np.linspace(-1.0, 1.0, OBS_DIM)
    live_action, live = agent._act(obs), _params(agent.policy_module)
    with torch.no_grad():
        ema_action = torch.tanh(agent.policy_ema._mean_log_std(torch.as_tensor(obs, dtype=torch.float32)[None])[0][0])
    with agent.averaged_actor():
        np.testing.assert_allclose(agent._act(obs), ema_action.numpy(), atol=1e-6)
    np.testing.assert_array_equal(agent._act(obs), live_action)
    with pytest.raises(RuntimeError, match="inside"):
        with agent.averaged_actor():
            raise RuntimeError("inside")
    assert all(torch.equal(a, b) for a, b in zip(live, _params(agent.policy_module)))
    with pytest.raises(ValueError, match="actor_ema"):
        with _agent(SQIL).averaged_actor():
            pass


@pytest.mark.parametrize("rate", [0.0, -0.1, 1.5])
def test_actor_average_rate_outside_the_unit_interval_rejected(rate):
    with pytest.raises(ValueError, match="actor_ema"):
        _agent(IQLearn, actor_ema=rate)


def test_actor_average_survives_a_checkpoint(tmp_path):
    agent = _agent(SQIL, actor_ema=0.2)
    agent.fit(_dataset(n=40))
    agent.save(tmp_path / "a.pt")
    loaded = SQIL.load(tmp_path / "a.pt")
    for a, b in zip(_params(agent.policy_ema), _params(loaded.policy_ema)):
        assert torch.equal(a, b)
    # the state of an agent without the average (a fork that adds actor_ema): the average starts at its actor
    plain = _agent(SQIL, seed=1)
    plain.fit(_dataset(n=40))
    forked = _agent(SQIL, seed=2, actor_ema=0.2)
    forked.load_state_dict(plain.state_dict())
    for a, b, c in zip(_params(plain.policy_module), _params(forked.policy_module), _params(forked.policy_ema)):
        assert torch.equal(a, b) and torch.equal(a, c)


def test_loaded_state_keeps_the_configured_learning_rates():
    """A fork with changed learning rates trains with the new ones: loading a state restores the optimizers'
    moments, not the source run's learning rates (torch's Optimizer.load_state_dict alone would)."""
    source = _agent(LSIQ, critic_lr=3e-4, actor_lr=3e-5)
    source.fit(_dataset(n=40))
    fork = _agent(LSIQ, seed=1, critic_lr=1e-5, actor_lr=1e-6)
    fork.load_state_dict(source.state_dict())
    assert [g["lr"] for g in fork.sac.critic_opt.param_groups] == [1e-5]
    assert [g["lr"] for g in fork.sac.actor_opt.param_groups] == [1e-6]
    for name in ("critic_opt", "actor_opt"):        # the moments are the source's
        mine, theirs = getattr(fork.sac, name).state_dict()["state"], getattr(source.sac, name).state_dict()["state"]
        assert mine.keys() == theirs.keys() and len(mine) > 0
        for k in mine:
            assert torch.equal(mine[k]["exp_avg_sq"], theirs[k]["exp_avg_sq"])
    # the step the fork takes is the new rate's: at a thirtieth of the critic rate the critic moves far less
    same = _agent(LSIQ, seed=1, critic_lr=3e-4, actor_lr=3e-5)
    same.load_state_dict(source.state_dict())
    before = [p.clone() for p in source.sac.critic.parameters()]
    batch = _dataset(n=1, seed=9)
    moved = []
    for agent in (same, fork):
        agent.replay.load_state_dict(source.replay.state_dict())   # not part of the agent's state
        agent.fit(batch)
        assert agent.n_updates == source.n_updates + 1
        moved.append(sum((p - b).abs().sum().item() for p, b in zip(agent.sac.critic.parameters(), before)))
    assert moved[1] < 0.1 * moved[0]


def test_frozen_replay_keeps_updating_on_the_stored_transitions():
    agent = _agent(SQIL)
    agent.fit(_dataset(n=40))
    stored = agent.replay.state_dict()
    updates = agent.n_updates
    agent.ablations = dataclasses.replace(agent.ablations, freeze_replay=True)   # as a fork with freeze_replay=true
    agent.fit(_dataset(n=10, seed=3))
    assert agent.n_updates == updates + 10 and agent.n_transitions == 50
    for key, value in agent.replay.state_dict().items():   # nothing new stored
        assert np.array_equal(np.asarray(value), np.asarray(stored[key])), key
    empty = _agent(SQIL, ablations=Ablations(freeze_replay=True))
    with pytest.raises(RuntimeError, match="no update would ever run"):
        empty.fit(_dataset(n=10))


def _random_action_gap(agent, obs: torch.Tensor, actions: torch.Tensor, k: int = 64) -> float:
    """Mean over states of max_k Q(s, a_k) - Q(s, a_stored), a_k uniform random (the diagnostics' Q gap)."""
    gen = torch.Generator().manual_seed(0)
    with torch.no_grad():
        q_rand = torch.stack([agent.sac.critic(obs, torch.rand(len(obs), ACT_DIM, generator=gen) * 2 - 1)[0]
                              for _ in range(k)])
        return (q_rand.amax(0) - agent.sac.critic(obs, actions)[0]).mean().item()


def test_conservative_weight_ranks_random_actions_closer_to_the_stored_ones():
    # the agent always took the same action; the mixture loss pushes its Q down (towards r_min + gamma V(s'))
    # and leaves other actions free, so the best random action ends up above it: the Q gap of the diagnostics
    data = [(o, np.full(ACT_DIM, 0.5), r, o2, ab, last) for o, _, r, o2, ab, last in _dataset(n=600)]
    gaps = {}
    for weight, hinge in ((0.0, False), (5.0, False), (5.0, True)):
        ablations = Ablations(conservative_weight=weight, conservative_actions=4, conservative_hinge=hinge)
        agent = _agent(LSIQ, objective="mixture", critic_lr=1e-3, ablations=ablations)
        agent.fit(data)
        assert ("conservative_penalty" in agent.last_info) == (weight > 0)
        replay = agent.replay.sample(256, np.random.default_rng(1))
        gaps[weight, hinge] = _random_action_gap(agent, replay["obs"], replay["actions"])
    off = gaps[0.0, False]
    assert off > 1.0 and gaps[5.0, False] < 0.5 * off and gaps[5.0, True] < 0.5 * off, gaps


@pytest.mark.parametrize("kw", [{"conservative_weight": -1.0}, {"conservative_actions": 0}])
def test_conservative_penalty_settings_rejected(kw):
    with pytest.raises(ValueError, match="conservative"):
        _agent(SQIL, ablations=Ablations(**kw))


def test_actor_bc_term_pulls_the_mean_action_to_the_expert_actions():
    expert = _expert()
    expert.actions = np.tanh(expert.obs[:, :ACT_DIM])          # a learnable expert: its action follows its state
    obs, actions = (torch.as_tensor(x, dtype=torch.float32) for x in (expert.obs, expert.actions))
    errors = {}
    for bc_alpha in (None, 0.1):
        agent = _agent(LSIQ, actor_lr=1e-3, ablations=Ablations(actor_bc_alpha=bc_alpha))
        agent.set_expert(expert)
        agent.fit(_dataset(n=300))
        with torch.no_grad():
            errors[bc_alpha] = (agent.policy_module.deterministic(obs) - actions).pow(2).sum(-1).mean().item()
    assert errors[0.1] < 0.5 * errors[None], errors


def test_actor_bc_settings_rejected():
    with pytest.raises(ValueError, match="actor_bc_alpha must be > 0"):
        _agent(SQIL, ablations=Ablations(actor_bc_alpha=0.0))
    with pytest.raises(ValueError, match="state-only"):
        _agent(LSIQfO, ablations=Ablations(actor_bc_alpha=2.5))
