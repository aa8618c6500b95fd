"""Learning tests of the off-policy IL agents (IQ-Learn, LS-IQ, LSIQ-fO, SQIL) on a cheap task.

Task: the project's own `LocoEnv.make("InvertedPendulum.balance.perfect", seed=...)` (Gymnasium
InvertedPendulum-v5's dynamics, reward and termination, checked step by step in
tests/environments/test_classic_match_gymnasium.py; observation q_slider, q_hinge, dq_slider, dq_hinge;
actions normalized to [-1, 1]; return = steps survived, at most 1000). The expert is a hand-tuned
linear state feedback controller that balances for the full 1000 steps; the demonstrations are 10
of its episodes. Every agent must reach >= 80 % of the expert return, evaluated with the
deterministic policy, within a small budget of environment steps, with fixed seeds. A
random/untrained policy scores ~5-30, so these tests fail when learning is broken.
"""
from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from mushroom_rl.core import Core

from loco_il import LocoEnv
from loco_il.rl.networks import GaussianPolicy
from loco_il.algorithms.iq_learn import IQLearn
from loco_il.algorithms.lsiq import LSIQ, LSIQfO
from loco_il.algorithms.sqil import SQIL

pytestmark = pytest.mark.slow      # learning tests: the full suite (CI) runs them; -m "not slow" skips them

ACTION_SCALE = 3.0                                  # force range [-3, 3] <-> normalized action [-1, 1]
EXPERT_GAINS = np.array([1.0, 10.0, 1.0, 1.0])      # obs = [cart pos, pole angle, cart vel, pole ang. vel]
EXPERT_NOISE = 0.2
HORIZON = 1000


def make_env(seed: int):
    """The pendulum task; `seed` seeds the env's RNG once, later resets continue its stream."""
    env = LocoEnv.make("InvertedPendulum.balance.perfect", seed=seed)
    assert tuple(env.obs_spec.names) == ("q_slider", "q_hinge", "dq_slider", "dq_hinge")
    assert env.info.horizon == HORIZON
    return env


def expert_action(obs: np.ndarray) -> np.ndarray:
    return np.clip(np.array([EXPERT_GAINS @ obs]) / ACTION_SCALE, -1.0, 1.0)


def rollout(env, act, n_episodes: int):
    """Returns (list of episode returns, transitions dict)."""
    returns, rows = [], []
    for _ in range(n_episodes):
        obs, ret = env.reset(), 0.0
        for t in range(HORIZON):
            a = act(obs)
            nxt, r, absorbing, _ = env.step(a)
            ret += r
            rows.append((obs, a, nxt, absorbing, absorbing or t == HORIZON - 1))
            obs = nxt
            if absorbing:
                break
        returns.append(ret)
    obs, a, nxt, ab, last = map(np.array, zip(*rows))
    return returns, dict(obs=obs, actions=a, next_obs=nxt, absorbing=ab, last=last)


def make_expert_data(n_episodes: int = 10, seed: int = 123):
    """Demonstrations of the controller with Gaussian action noise (std 0.2 of the normalized range).

    Without noise the controller's 10 episodes sit almost exactly at the upright fixed point
    (state std ~0.003), which says nothing about how to recover from perturbations; with the
    noise the demonstrations cover the neighbourhood of the upright state and still never fall.
    """
    rng = np.random.default_rng(seed)
    act = lambda obs: np.clip(expert_action(obs) + EXPERT_NOISE * rng.standard_normal(1), -1.0, 1.0)  # noqa: E731
    returns, d = rollout(make_env(seed), act, n_episodes)
    assert min(returns) == HORIZON, "the hand-tuned expert must balance for the whole episode"
    return SimpleNamespace(rewards=np.ones(len(d["obs"])), info={}, **d)


@pytest.fixture(scope="module")
def expert_data():
    return make_expert_data()


def evaluate(agent, n_episodes: int = 3, seed: int = 7) -> float:
    agent.deterministic = True
    try:
        returns, _ = rollout(make_env(seed), agent.draw_action, n_episodes)
    finally:
        agent.deterministic = False
    return float(np.mean(returns))


# Test-size settings (not the paper defaults, see experiment_configs/algo/*.yaml): small nets,
# 128 + 128 samples per update, critic lr 1e-3, faster target tracking (tau 0.02) and a small fixed
# temperature (the task's reward scale is ~1; with SAC's alpha = 1 start the entropy bonus swamps it).
COMMON = dict(critic_hidden=(64, 64), batch_size=128, expert_batch_size=128, initial_replay_size=500,
              replay_capacity=20_000, critic_lr=1e-3, actor_lr=3e-4, tau=0.02, init_alpha=0.01,
              learn_alpha=False)
ENV_STEPS = 5000

CASES = {  # name: (class, extra kwargs, env steps)
    "iqlearn": (IQLearn, {}, ENV_STEPS),
    # LS-IQ's default objective (the released runs' "fixed_expert") learns this task more slowly. With the
    # twin critic (n_critics=2) 2 of 4 seeds balanced after 10000 steps, all 4 after
    # 15000; with one critic (the default) seeds 0-3 balance after 10000 steps, seeds 1-5 after 15000, and
    # seed 0 had fallen again at 15000 and balanced at 20000 (benchmarks/RESULTS.md)
    "lsiq": (LSIQ, {}, 2 * ENV_STEPS),
    "lsiq_twin_critic": (LSIQ, dict(n_critics=2), 3 * ENV_STEPS),
    "lsiq_mixture": (LSIQ, dict(objective="mixture"), ENV_STEPS),
    "lsiqfo": (LSIQfO, dict(idm_hidden=(64, 64)), 3 * ENV_STEPS),  # the same default objective; one critic:
    # seeds 0 and 1 balanced after 10000 steps in one uninterrupted Core.learn (mujoco 4.0);
    # evaluated every 2500 steps with mujoco 3.17, seed 0 had 209 at 10000
    "sqil": (SQIL, {}, ENV_STEPS),
}


EVAL_EVERY = 2500   # env steps between the evaluations of a learning run


def train(name: str, expert, seed: int = 0, n_steps: int | None = None,
          eval_every: int | None = None) -> tuple[object, list[tuple[int, float]]]:
    """(agent, [(env steps, evaluation return), ...]): with `eval_every`, the agent is evaluated after every
    `eval_every` env steps (Core.learn resumes in chunks), else once at the end."""
    torch.set_num_threads(1)
    torch.manual_seed(seed)
    cls, extra, env_steps = CASES[name]
    env = make_env(seed)
    policy = GaussianPolicy(4, 1, hidden=(64, 64), squash=True)
    agent = cls(env.info, policy, seed=seed, **COMMON, **extra)
    agent.set_expert(expert)
    core = Core(agent, env)
    total, chunk = n_steps or env_steps, eval_every or n_steps or env_steps
    curve, done = [], 0
    while done < total:
        core.learn(n_steps=min(chunk, total - done), n_steps_per_fit=1, quiet=True)
        done += min(chunk, total - done)
        if eval_every:
            curve.append((done, evaluate(agent)))
    return agent, curve


@pytest.mark.parametrize("name", list(CASES))
def test_reaches_expert_return(name, expert_data):
    """The issue's learning test: each learner is at >= 0.8 of the expert's return at the end of its budget. The
    curve (an evaluation every EVAL_EVERY env steps) is printed: LS-IQ's learners reach the expert and can fall
    off it again (see CASES and benchmarks/RESULTS.md)."""
    if name == "lsiqfo":
        expert_data = SimpleNamespace(**{**vars(expert_data), "actions": None})  # state-only demonstrations
    start, cpu_start = time.perf_counter(), time.process_time()
    _, curve = train(name, expert_data, eval_every=EVAL_EVERY)
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    points = " ".join(f"{steps}:{ret:.0f}" for steps, ret in curve)
    print(f"{name}: returns {points} (expert {HORIZON}), {elapsed:.1f} s wall, {cpu:.1f} s CPU")
    final = curve[-1][1]
    assert final >= 0.8 * HORIZON, f"{name} ends at {final:.0f} of the expert's {HORIZON} ({points})"
