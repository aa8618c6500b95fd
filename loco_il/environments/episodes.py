"""Episodes: the one loop that runs a policy in an env, for datasets, evaluation, baselines and the rollout command.

**An episode** of ``policy`` starts from ``env.seed(seed); obs = env.reset()``. The policy's optional
``start_episode(env, seed)`` hook is then called (the policy interface of `loco_il.experts.files`: experts with a
phase clock or a model of the robot start it there), and the env is stepped with ``policy(obs)`` until a step is
absorbing (a fall or a divergence) or ``horizon`` steps have passed. `run_episode` runs one, `run_episodes` one
per reset seed, `episode_seeds` gives the reset seeds every dataset, evaluation and baseline uses, and
`replay_episode` steps recorded actions from a stored simulator state (how a dataset is checked to be exact).

**Options** of `run_episode`, by caller:

* ``record``: keep every transition (obs, action, next obs) and the start state (qpos, qvel and the horizontal
  position of the task's velocity point, also at the end, for the forward speed). Datasets
  (`loco_il.datasets.providers.expert.rollout_episode`), baselines and `experts eval` (`evaluate_task`)
  and the evaluation's visited states (`loco_il.evaluation.evaluate_policy` with ``collect_obs``).
* ``clip``: check each action (size, finite) and clip it to [-1, 1] before stepping, so a recorded action is
  exactly the executed one and a bad expert is named as the culprit (datasets, baselines).
* ``on_state(env)``: called once the episode has started and after every step; the video recorder
  (`loco_il.environments.rendering.record_episode`) renders a frame there.

Without options it is the rollout command's loop (``python -m loco_il.rollout``).

The env is a `LocoEnv` or anything with its mushroom-rl interface (``seed``, ``reset``, ``step(a) -> (obs,
reward, absorbing, info)``); ``record`` also needs ``get_sim_state`` and ``horizontal_position``, ``clip``
``model.nu``. The expert trainers' vectorized evaluation (`loco_il.experts.vec`) steps many envs in lockstep
instead and shares only the per-episode outcome (`Outcome`, `outcome_arrays`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping, NamedTuple, Sequence

import numpy as np

Policy = Callable[[np.ndarray], np.ndarray]
#: ``act(obs, t) -> action`` at step ``t`` of an episode: a policy's action, or a recorded one when replaying
Act = Callable[[np.ndarray, int], np.ndarray]


def episode_seeds(seed: int, n: int) -> np.ndarray:
    """Reset seed of episode i: ``SeedSequence(seed, spawn_key=(i,))`` -> uint32; prefix-stable in n."""
    return np.array([np.random.SeedSequence(int(seed), spawn_key=(i,)).generate_state(1, np.uint32)[0]
                     for i in range(int(n))], dtype=np.int64)


def start_episode(policy: Any, env: Any, seed: int) -> None:
    """Call the policy's optional ``start_episode(env, seed)`` hook (the policy interface: `loco_il.experts.files`)."""
    hook = getattr(policy, "start_episode", None)
    if callable(hook):
        hook(env, int(seed))


class UniformRandomPolicy:
    """Uniform random actions in [-1, 1] of ``shape`` from one generator (the random policy of the baselines
    and the rollout command); successive episodes continue the generator's stream."""

    def __init__(self, shape: int | tuple[int, ...], rng: np.random.Generator):
        self.shape, self.rng = shape, rng

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.rng.uniform(-1.0, 1.0, self.shape)


class Outcome(NamedTuple):
    """How an episode ended: its return, its number of steps and whether a terminal state (a fall) ended it
    before the horizon."""

    ret: float
    length: int
    terminated: bool


def outcome_arrays(outcomes: Sequence[Outcome]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(returns, lengths, terminated) of episodes, as float64, int64 and bool arrays."""
    return (np.array([o.ret for o in outcomes], dtype=np.float64),
            np.array([o.length for o in outcomes], dtype=np.int64),
            np.array([o.terminated for o in outcomes], dtype=bool))


@dataclass
class Episode:
    """One episode. ``ret`` sums the rewards step by step; the datasets and baselines store ``np.sum(rewards)``
    (pairwise summation, which can differ from it in the last bits), as they always have. The fields after
    ``terminated`` are None unless the episode was recorded."""

    seed: int | None
    start_obs: np.ndarray          # the first observation (after the reset, or the stored state of a replay)
    rewards: np.ndarray            # float64, one per step
    ret: float
    terminated: bool               # the last step was absorbing
    obs: np.ndarray | None = None          # before each step
    actions: np.ndarray | None = None      # as passed to env.step (float64)
    next_obs: np.ndarray | None = None
    qpos: np.ndarray | None = None         # simulator state after the reset
    qvel: np.ndarray | None = None
    xy_start: np.ndarray | None = None     # horizontal position of the task's velocity point after the reset
    xy_end: np.ndarray | None = None       # ... and after the last step

    @property
    def length(self) -> int:
        return len(self.rewards)

    @property
    def outcome(self) -> Outcome:
        return Outcome(self.ret, self.length, self.terminated)

    @property
    def absorbing(self) -> np.ndarray:
        """Per step: only the last step can be absorbing (the loop stops there)."""
        flags = np.zeros(self.length, dtype=bool)
        if self.length:
            flags[-1] = self.terminated
        return flags

    def forward_speed(self, dt: float) -> float:
        """Mean x velocity (m/s) of the task's velocity point, for a recorded episode of control step ``dt``."""
        if self.xy_start is None or self.xy_end is None:
            raise ValueError("the forward speed needs a recorded episode (record=True)")
        return float(self.xy_end[0] - self.xy_start[0]) / (self.length * dt)


def run_episode(env: Any, policy: Policy, seed: int, horizon: int, *, record: bool = False, clip: bool = False,
                on_state: Callable[[Any], None] | None = None) -> Episode:
    """One episode of ``policy`` from ``env.seed(seed); env.reset()``, at most ``horizon`` steps (the options:
    see the module docstring). Depends on nothing but the seed (and, for a stochastic policy, its own state)."""
    env.seed(int(seed))
    obs = env.reset()
    start = _start_state(env) if record else {}
    start_episode(policy, env, seed)
    if on_state is not None:
        on_state(env)
    act = _checked_actions(policy, int(env.model.nu), int(seed)) if clip else _actions(policy)
    episode = _play(env, obs, act, int(horizon), record=record, on_state=on_state)
    episode.seed = int(seed)
    if record:
        episode.qpos, episode.qvel, episode.xy_start = start["qpos"], start["qvel"], start["xy"]
        episode.xy_end = env.horizontal_position()
    return episode


def run_episodes(env: Any, policy: Policy, seeds: Sequence[int], horizon: int, *, record: bool = False,
                 clip: bool = False, on_episode: Callable[[int, Episode], None] | None = None) -> list[Episode]:
    """`run_episode` for each reset seed in order; ``on_episode(i, episode)`` after each (progress output)."""
    episodes = []
    for i, seed in enumerate(seeds):
        episodes.append(run_episode(env, policy, int(seed), horizon, record=record, clip=clip))
        if on_episode is not None:
            on_episode(i, episodes[-1])
    return episodes


def replay_episode(env: Any, qpos: np.ndarray, qvel: np.ndarray, actions: np.ndarray,
                   seed: int | None = None) -> dict[str, np.ndarray]:
    """Replay recorded actions from a stored initial state; returns obs, next_obs, rewards, absorbing.

    With ``seed`` the env is first reset with that seed (reproducing a sampled task command and the
    env's random stream); the simulator is then put in ``(qpos, qvel)``. ``env`` must emit the same
    observations as the recording env (no ``.pomdp``).
    """
    if seed is not None and int(seed) >= 0:
        env.seed(int(seed))
    env.reset()
    obs = env.set_sim_state(np.asarray(qpos, dtype=np.float64), np.asarray(qvel, dtype=np.float64))
    actions = np.asarray(actions)
    episode = _play(env, obs, lambda _, t: actions[t], len(actions), record=True)
    return {"obs": episode.obs, "next_obs": episode.next_obs, "rewards": episode.rewards,
            "absorbing": episode.absorbing}


# ----------------------------------------------------------------------------- the loop and its parts


def _play(env: Any, obs: np.ndarray, act: Act, n_steps: int, *, record: bool,
          on_state: Callable[[Any], None] | None = None) -> Episode:
    """Step ``env`` from ``obs`` with ``act(obs, t)`` for at most ``n_steps`` steps, stopping after an absorbing
    one (shared by episodes and replays)."""
    start_obs = np.array(obs, dtype=np.float64)
    rewards: list[float] = []
    seen: dict[str, list[np.ndarray]] = {"obs": [], "actions": [], "next_obs": []}
    total, absorbing = 0.0, False
    for t in range(n_steps):
        action = act(obs, t)
        next_obs, reward, absorbing, _ = env.step(action)
        total += float(reward)
        rewards.append(reward)
        if record:
            for key, value in zip(seen, (obs, action, next_obs)):
                seen[key].append(value)
        if on_state is not None:
            on_state(env)
        obs = next_obs
        if absorbing:
            break
    kept = {k: np.asarray(v, dtype=np.float64) for k, v in seen.items()} if record else {}
    return Episode(seed=None, start_obs=start_obs, rewards=np.asarray(rewards, dtype=np.float64),
                   ret=total, terminated=bool(absorbing), **kept)


def _start_state(env: Any) -> dict[str, np.ndarray]:
    qpos, qvel = env.get_sim_state()
    return {"qpos": np.asarray(qpos), "qvel": np.asarray(qvel), "xy": env.horizontal_position()}


def _actions(policy: Policy) -> Act:
    return lambda obs, t: np.asarray(policy(obs), dtype=np.float64)


def _checked_actions(policy: Policy, act_dim: int, seed: int) -> Act:
    """The policy's actions, refused when of the wrong size or not finite and clipped to [-1, 1]: what
    `LocoEnv.step` applies anyway, done here so the recorded action is exactly the executed one."""
    def act(obs: np.ndarray, t: int) -> np.ndarray:
        a = np.asarray(policy(obs), dtype=np.float64).reshape(-1)
        if a.shape != (act_dim,):
            raise ValueError(f"the expert returned an action of shape {a.shape}, the env needs ({act_dim},)")
        if not np.isfinite(a).all():
            raise ValueError(f"the expert returned a non-finite action at step {t} of the episode with reset "
                             f"seed {seed}: {a}")
        return np.clip(a, -1.0, 1.0)
    return act


__all__ = ["Episode", "Outcome", "UniformRandomPolicy", "episode_seeds", "outcome_arrays", "replay_episode",
           "run_episode", "run_episodes", "start_episode"]


def evaluate_task(task_id: str, policy: Callable[[np.ndarray], np.ndarray] | None, episodes: int, seed: int,
                  log: Callable[[str], None] | None = None, details: bool = False,
                  env_kwargs: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Mean/std return of a deterministic policy (None = uniform random actions in [-1, 1]) over
    ``episodes`` episodes whose reset seeds come from ``episode_seeds(seed, episodes)``, rolled out as the
    datasets are (`run_episode` with ``record=True, clip=True``: the policy's
    optional ``start_episode(env, seed)`` hook is called after every reset). ``details``: also per-episode
    ``returns``, ``lengths``, ``terminated`` (ended by a fall or divergence before the horizon) and
    ``forward_speed`` (mean x velocity of the task's velocity point, m/s).
    ``env_kwargs`` go to the env (e.g. ``init_state_sampler``: other start states)."""
    from loco_il.environments.registry import get_body, make, task_key
    key = task_key(task_id)
    body = get_body(key.split(".")[0].split("-")[0])
    env = make(f"{key}.{body.default_dataset}", **dict(env_kwargs or {}))
    if policy is None:
        policy = UniformRandomPolicy(int(env.model.nu), np.random.default_rng(seed))
    returns, lengths, terminated, speeds = [], [], [], []

    def measure(i: int, ep: Episode) -> None:
        returns.append(float(np.sum(ep.rewards)))     # as the datasets sum an episode's rewards
        lengths.append(ep.length)
        terminated.append(ep.terminated)
        speeds.append(ep.forward_speed(env.dt))
        if log:
            log(f"[baselines] {task_id}: episode {i + 1}/{episodes} return {returns[-1]:.2f} "
                f"length {lengths[-1]} speed {speeds[-1]:.3f} m/s")

    try:
        run_episodes(env, policy, episode_seeds(seed, episodes), int(env.info.horizon), record=True, clip=True,
                     on_episode=measure)
    finally:
        env.stop()
    out = {"return_mean": float(np.mean(returns)), "return_std": float(np.std(returns)), "episodes": int(episodes),
           "seed": int(seed), "mean_episode_length": float(np.mean(lengths))}
    if details:
        out.update(returns=returns, lengths=lengths, terminated=terminated, forward_speed=speeds)
    return out
