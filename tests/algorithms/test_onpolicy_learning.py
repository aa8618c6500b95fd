"""Learning tests: GAIL, VAIL, GAIfO and BC imitate a balancing expert on InvertedPendulum.

Environment: `loco_il.LocoEnv.make("InvertedPendulum.balance.perfect")` when it can be built, otherwise
Gymnasium's `InvertedPendulum-v5` behind a tiny mushroom-rl adapter (actions in [-1, 1], scaled by 3).
Observations are [cart pos, pole angle, cart vel, pole angular vel] in both.
Expert: a hand-tuned linear state feedback u = K (obs - [X_REF, 0, 0, 0]) (force units), which balances
for the full 1000 steps while holding the cart near X_REF (steady state ~0.52). Demonstrations: 10 expert
episodes, recorded with noise injected into the executed actions (see `rollout`).
Each algorithm must, with the deterministic (mean) policy, within a fixed step budget and fixed seeds,
(a) reach THRESHOLD of the expert's return and (b) hold the cart where the expert holds it (mean cart
position over the second half of the episodes within CART_TOL of the expert's). (b) is what a policy
that merely survives does not do (the -log(1 - D) reward is positive, a survival bonus; TRPO on a
constant reward balanced with the cart at -0.17..0.27 in our checks).
"""
from __future__ import annotations

import time
import types

import numpy as np
import pytest
import torch
from mushroom_rl.core import Core, MDPInfo
from mushroom_rl.utils.spaces import Box

from loco_il.algorithms.bc import BC
from loco_il.rl.networks import GaussianPolicy
from loco_il.algorithms.gaifo import GAIfO
from loco_il.algorithms.gail import GAIL
from loco_il.algorithms.vail import VAIL

pytestmark = pytest.mark.slow      # learning tests: the full suite (CI) runs them; -m "not slow" skips them

torch.set_num_threads(1)

K_FORCE = np.array([1.0, 10.0, 1.0, 1.0])  # u = K obs balances InvertedPendulum (checked: 1000/1000 steps)
X_REF = np.array([0.5, 0.0, 0.0, 0.0])     # the expert's cart set-point
CART_TOL = 0.15
ACTION_SCALE = 3.0                          # InvertedPendulum's force range is [-3, 3]
THRESHOLD = 0.8                             # fraction of the expert's return to reach
N_DEMO_EPISODES = 10
BC_STEPS = 500
DEMO_NOISE = 0.1                            # std of the executed-action noise in the demos


class GymInvertedPendulum:
    """Gymnasium InvertedPendulum-v5 with the mushroom-rl Environment interface and actions in [-1, 1]."""

    def __init__(self):
        import gymnasium as gym
        self._env = gym.make("InvertedPendulum-v5").unwrapped  # Core enforces the horizon
        obs_space = Box(np.full(4, -np.inf), np.full(4, np.inf))
        self.info = MDPInfo(obs_space, Box(-np.ones(1), np.ones(1)), gamma=0.99, horizon=1000)
        self._seed = None

    def seed(self, seed):
        self._seed = seed

    def reset(self, state=None):
        obs, _ = self._env.reset(seed=self._seed)
        self._seed = None
        return obs

    def step(self, action):
        force = ACTION_SCALE * np.clip(np.asarray(action, dtype=np.float64).reshape(1), -1.0, 1.0)
        obs, reward, terminated, _, _ = self._env.step(force)
        return obs, float(reward), bool(terminated), {}

    def render(self, record=False):
        pass

    def stop(self):
        pass


def make_env():
    try:
        from loco_il import LocoEnv
        env = LocoEnv.make("InvertedPendulum.balance.perfect")
        return env, "loco_il InvertedPendulum.balance.perfect"
    except Exception:  # LocoEnv (or this task) not available: fall back to Gymnasium
        return GymInvertedPendulum(), "gymnasium InvertedPendulum-v5"


def expert_action(obs):
    return np.clip(np.array([K_FORCE @ (obs - X_REF)]) / ACTION_SCALE, -1.0, 1.0)


def rollout(env, act, n_episodes, seed, exec_noise=0.0):
    """Episodes with `act(obs)`: the transitions (a Trajectories), the episode returns and the mean cart
    position over the second halves of the episodes. With `exec_noise` > 0 the environment executes
    act(obs) + N(0, exec_noise^2) while the recorded action stays act(obs) (noise injection in the
    demonstrations, DART, Laskey et al. 2017: the demos then cover states around the expert's path)."""
    rows, returns, carts = [], [], []
    noise_rng = np.random.default_rng(seed)
    env.seed(seed)
    horizon = env.info.horizon
    for _ in range(n_episodes):
        obs, ret, xs = env.reset(), 0.0, []
        for t in range(horizon):
            a = act(obs)
            executed = a + exec_noise * noise_rng.normal(size=a.shape) if exec_noise else a
            nxt, r, absorbing, _ = env.step(executed)
            last = absorbing or t == horizon - 1
            rows.append((obs, a, r, nxt, absorbing, last))
            ret += r
            xs.append(nxt[0])
            obs = nxt
            if last:
                break
        returns.append(ret)
        carts.append(np.mean(xs[len(xs) // 2:]))
    s, a, r, s2, ab, la = (np.array(x) for x in zip(*rows))
    fields = dict(obs=s.astype(np.float64), actions=a.astype(np.float64), rewards=r.astype(np.float64),
                  next_obs=s2.astype(np.float64), absorbing=ab.astype(bool), last=la.astype(bool))
    try:  # the project's dataset class when it is there (validates the arrays)
        from loco_il.datasets.trajectory import Trajectories
        data = Trajectories(**fields, info={"dataset_type": "perfect", "source": "linear controller (test)"})
    except ImportError:
        data = types.SimpleNamespace(**fields)
    return data, np.array(returns), float(np.mean(carts))


@pytest.fixture(scope="module")
def setting():
    env, source = make_env()
    demos, demo_returns, _ = rollout(env, expert_action, N_DEMO_EPISODES, seed=123, exec_noise=DEMO_NOISE)
    assert demo_returns.min() >= 0.95 * env.info.horizon, f"the noisy linear expert fails on {source}"
    _, expert_returns, expert_cart = rollout(env, expert_action, 3, seed=1000)  # as the agents are evaluated
    assert expert_returns.min() >= 0.95 * env.info.horizon, f"the linear expert fails on {source}"
    return env, source, demos, (float(expert_returns.mean()), expert_cart)


def evaluate(agent, env, n_episodes=3, seed=1000):
    agent.deterministic = True
    try:
        with torch.no_grad():
            _, returns, cart = rollout(env, agent.draw_action, n_episodes, seed)
    finally:
        agent.deterministic = False
    return float(returns.mean()), cart


def imitates(result, expert):
    (ret, cart), (expert_ret, expert_cart) = result, expert
    return ret >= THRESHOLD * expert_ret and abs(cart - expert_cart) <= CART_TOL


def policy(env, log_std=-0.5):
    return GaussianPolicy(env.info.observation_space.shape[0], env.info.action_space.shape[0],
                          hidden=(64, 64), squash=False, init_log_std=log_std)


ADVERSARIAL_KW = dict(disc_hidden=(64, 64), disc_lr=1e-3, disc_batch_size=1000, disc_updates_per_fit=5,
                      train_disc_every=1, max_kl=0.02, cg_iters=10, vf_hidden=(64, 64), vf_lr=3e-3,
                      vf_epochs=5, vf_batch_size=250)


def train_adversarial(agent, env, expert, max_steps, steps_per_fit=2000, eval_every=2):
    """Core.learn in chunks, deterministic evaluation after each; stops once the agent imitates."""
    core = Core(agent, env)
    start, steps, history = time.perf_counter(), 0, []
    while steps < max_steps:
        core.learn(n_steps=steps_per_fit * eval_every, n_steps_per_fit=steps_per_fit, quiet=True)
        steps += steps_per_fit * eval_every
        result = evaluate(agent, env)
        history.append((steps, tuple(round(x, 3) for x in result),
                        {k: round(v, 3) for k, v in agent.last_fit_info.items()}))
        if imitates(result, expert):
            break
    wall = time.perf_counter() - start
    print(f"\n{agent.pretty_name()}: (return, cart) {result} vs expert {expert} after {steps} steps, {wall:.1f} s")
    for h in history:
        print("   ", h)
    return result, wall


def _seed(seed):
    np.random.seed(seed)
    torch.manual_seed(seed)


@pytest.mark.parametrize("algo", [GAIL, VAIL, GAIfO], ids=["gail", "vail", "gaifo"])
def test_onpolicy_adversarial_imitates_balancing_expert(setting, algo):
    env, source, demos, expert = setting
    _seed(0)
    env.seed(0)
    algo.check_dataset_type("perfect")
    kwargs = dict(ADVERSARIAL_KW)
    if algo is VAIL:
        kwargs.update(z_dim=16, info_constraint=0.5, beta_lr=1e-3)
    agent = algo(env.info, policy(env), seed=0, **kwargs)
    agent.set_expert(demos)
    result, _ = train_adversarial(agent, env, expert, max_steps=120_000)
    assert imitates(result, expert), f"{agent.pretty_name()} on {source}: (return, cart) {result} vs expert {expert}"


def test_onpolicy_bc_imitates_balancing_expert(setting):
    env, source, demos, expert = setting
    _seed(0)
    agent = BC(env.info, policy(env), seed=0, lr=1e-3, batch_size=256)
    agent.set_expert(demos)
    start = time.perf_counter()
    agent.pretrain(BC_STEPS)
    result = evaluate(agent, env)
    print(f"\nBC: (return, cart) {result} vs expert {expert} after {BC_STEPS} updates, "
          f"{time.perf_counter() - start:.1f} s")
    assert imitates(result, expert), f"BC on {source}: (return, cart) {result} vs expert {expert}"
