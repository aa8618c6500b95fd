"""PPO expert pipeline: GAE, frozen normalizer, checkpoint/resume, learning, expert files, CLI."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch

from loco_il.experts import load_expert
from loco_il.experts.ppo import PPO, PPOTrainer, TrainConfig, compute_gae
from loco_il.experts.vec import make_vec_env

REPO = Path(__file__).resolve().parents[2]
TASK = "InvertedPendulum.balance.perfect"


def small_cfg(out_dir, **kw) -> dict:
    cfg = dict(task=TASK, num_envs=2, async_envs=False, device="cpu", out_dir=str(out_dir), total_steps=1024,
               num_steps=256, minibatch_size=128, epochs=2, eval_interval=0, eval_episodes=2, snapshot_every=0,
               log_interval_s=1000, checkpoint_minutes=100, seed=0)
    cfg.update(kw)
    return cfg


def quiet(_msg: str) -> None:
    pass


# ---------------------------------------------------------------------------- GAE
def test_gae_truncation_vs_termination_hand_computed():
    gamma, lam = 0.9, 0.8
    rewards = np.array([1.0, 1.0, 1.0])
    values = np.array([0.5, 0.6, 0.7])
    ended = np.array([False, True, False])            # the episode ends at t = 1
    # next_values[t] = V(s'_t): V(s_1) = 0.6; at t = 1 the real last observation has V = 2.0; after the
    # rollout V(s_3) = 0.9
    next_values = np.array([0.6, 2.0, 0.9])
    # terminated at t = 1: no bootstrap, recursion cut
    #   A2 = 1 + 0.9*0.9 - 0.7 = 1.11;  A1 = 1 - 0.6 = 0.4;  A0 = (1 + 0.9*0.6 - 0.5) + 0.72*0.4 = 1.328
    adv, ret = compute_gae(rewards, values, next_values, ended, ended, gamma, lam)
    np.testing.assert_allclose(adv, [1.328, 0.4, 1.11])
    np.testing.assert_allclose(ret, adv + values)
    # truncated at t = 1: bootstrap from V(s_T) = 2.0, recursion still cut
    #   A1 = 1 + 0.9*2.0 - 0.6 = 2.2;  A0 = 1.04 + 0.72*2.2 = 2.624
    adv_t, ret_t = compute_gae(rewards, values, next_values, np.zeros(3, bool), ended, gamma, lam)
    np.testing.assert_allclose(adv_t, [2.624, 2.2, 1.11])
    np.testing.assert_allclose(ret_t, adv_t + values)
    # (T, num_envs) layout gives the same per env
    adv2, _ = compute_gae(np.stack([rewards] * 2, 1), np.stack([values] * 2, 1), np.stack([next_values] * 2, 1),
                          np.stack([ended, np.zeros(3, bool)], 1), np.stack([ended] * 2, 1), gamma, lam)
    np.testing.assert_allclose(adv2[:, 0], adv)
    np.testing.assert_allclose(adv2[:, 1], adv_t)


class _Countdown(gym.Env):
    """obs = [t, 0, 0, 0]; truncated after 3 steps; the final observation is [3, 0, 0, 0]."""

    observation_space = gym.spaces.Box(-np.inf, np.inf, (4,), np.float64)
    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.t = 0
        return np.zeros(4), {}

    def step(self, action):
        self.t += 1
        return np.array([float(self.t), 0, 0, 0]), 1.0, False, self.t >= 3, {}


def test_rollout_bootstraps_from_the_real_last_observation_on_truncation(tmp_path):
    tr = PPOTrainer(small_cfg(tmp_path, num_steps=4, norm_obs=False, norm_reward=False), log=quiet)
    tr.envs = gym.vector.SyncVectorEnv([_Countdown] * 2, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
    tr.start()
    seen = []
    real_values = tr.agent.values
    tr.agent.values = lambda nobs: (seen.append(np.array(nobs)), real_values(nobs))[1]
    batch = tr.collect()
    tr.close()
    # first call: the final observations [3, 0, 0, 0] of the truncated episodes (t = 2), then the last obs
    np.testing.assert_array_equal(seen[0], np.array([[3.0, 0, 0, 0]] * 2, np.float32))
    # the returned value target at t = 2 is r + gamma * V([3, 0, 0, 0]) (lambda recursion cut there)
    with torch.no_grad():
        v_final = tr.agent.value(torch.tensor([[3.0, 0, 0, 0]])).item()
        v_2 = tr.agent.value(torch.tensor([[2.0, 0, 0, 0]])).item()
    returns = batch["returns"].reshape(4, 2)
    np.testing.assert_allclose(returns[2], 1.0 + 0.99 * v_final, rtol=1e-5)
    adv = batch["adv"].reshape(4, 2)
    np.testing.assert_allclose(adv[2], 1.0 + 0.99 * v_final - v_2, rtol=1e-4, atol=1e-6)


# ---------------------------------------------------------------------------- normalizer
def test_normalizer_frozen_in_evaluation(tmp_path):
    tr = PPOTrainer(small_cfg(tmp_path), log=quiet)
    tr.start()
    tr.collect()                        # training rollouts move the statistics ...
    rms = tr.agent.obs_rms
    before = (rms.mean.copy(), rms.var.copy(), rms.count)
    assert before[2] > 100
    tr.evaluate()                       # ... evaluation does not
    expert = tr.agent.make_expert()
    expert(np.random.default_rng(0).normal(size=(5, 4)) * 100)
    tr.close()
    np.testing.assert_array_equal(rms.mean, before[0])
    np.testing.assert_array_equal(rms.var, before[1])
    assert rms.count == before[2]
    np.testing.assert_array_equal(expert.obs_mean, before[0])


# ---------------------------------------------------------------------------- checkpoint / resume
def test_checkpoint_resume_continues_step_count(tmp_path):
    out = tmp_path / "run"
    s1 = PPOTrainer(small_cfg(out, total_steps=1024), log=quiet).train()
    assert s1["env_steps"] == 1024 and (out / "checkpoint.pt").exists() and (out / "best.pt").exists()
    saved = torch.load(out / "checkpoint.pt", weights_only=True)
    assert saved["step"] == 1024 and saved["iteration"] == 2
    tr = PPOTrainer(small_cfg(out, total_steps=2048), log=quiet)
    assert tr.resumed_from == 1024 and tr.step == 1024 and tr.iteration == 2
    for k, v in saved["agent"]["policy"].items():
        assert torch.equal(tr.agent.policy.state_dict()[k], v)
    s2 = tr.train()
    assert s2["resumed_from"] == 1024 and s2["env_steps"] == 2048
    assert torch.load(out / "checkpoint.pt", weights_only=True)["iteration"] == 4


def test_kill_after_periodic_checkpoint_then_resume(tmp_path):
    out = tmp_path / "run"

    class Killed(Exception):
        pass

    def kill_after_two(trainer):
        if trainer.iteration == 2:
            raise Killed

    tr = PPOTrainer(small_cfg(out, total_steps=4096, checkpoint_minutes=0), log=quiet)
    with pytest.raises(Killed):
        tr.train(callback=kill_after_two)     # checkpoint_minutes=0: a checkpoint after every iteration
    weights = {k: v.clone() for k, v in tr.agent.policy.state_dict().items()}
    resumed = PPOTrainer(small_cfg(out, total_steps=1536), log=quiet)
    assert resumed.step == 1024 and resumed.iteration == 2
    for k, v in weights.items():
        assert torch.equal(resumed.agent.policy.state_dict()[k], v)
    assert resumed.train()["env_steps"] == 1536


def test_sigterm_stops_after_the_iteration_with_a_checkpoint(tmp_path):
    out = tmp_path / "run"
    before = signal.getsignal(signal.SIGTERM)
    messages: list[str] = []

    def terminate_at_two(trainer):
        if trainer.iteration == 2:
            os.kill(os.getpid(), signal.SIGTERM)     # as `kill` or a cluster scheduler would

    summary = PPOTrainer(small_cfg(out, total_steps=4096), log=messages.append).train(callback=terminate_at_two)
    assert summary["stopped_by_signal"] == "SIGTERM" and summary["env_steps"] == 1024
    assert torch.load(out / "checkpoint.pt", weights_only=True)["step"] == 1024
    assert not (out / "final.pt").exists() and any("run the same command again" in m for m in messages)
    assert signal.getsignal(signal.SIGTERM) is before          # handlers are restored after training
    resumed = PPOTrainer(small_cfg(out, total_steps=1536), log=quiet)
    assert resumed.step == 1024
    done = resumed.train()
    assert done["env_steps"] == 1536 and done["stopped_by_signal"] is None and (out / "final.pt").exists()


# ---------------------------------------------------------------------------- learning
@pytest.mark.slow
def test_ppo_learns_inverted_pendulum(tmp_path):
    cfg = small_cfg(tmp_path, total_steps=12288, lr=1e-3, num_steps=256, minibatch_size=64, epochs=10,
                    eval_episodes=10, eval_envs=10)
    summary = PPOTrainer(cfg, log=quiet).train()
    assert summary["eval_return_mean"] >= 500, summary


# ---------------------------------------------------------------------------- expert files
def test_expert_round_trip_identical_actions(tmp_path):
    torch.manual_seed(0)
    cfg = TrainConfig(hidden=(32, 32))
    agent = PPO(4, 1, cfg)
    rng = np.random.default_rng(0)
    agent.obs_rms.update(rng.normal(2.0, 3.0, size=(500, 4)))
    with torch.no_grad():
        agent.policy.net[-1].weight.normal_()      # make the mean action depend on the input
    expert = agent.make_expert({"task_id": TASK, "training_steps": 123, "eval_return": 1.5})
    checksum = expert.save(tmp_path / "e.pt")
    raw = torch.load(tmp_path / "e.pt", weights_only=True)            # plain tensors and dicts only
    assert raw["metadata"]["task_id"] == TASK and raw["metadata"]["obs_dim"] == 4
    loaded = load_expert(tmp_path / "e.pt")
    assert loaded.checksum() == checksum == expert.checksum()
    assert loaded.metadata["training_steps"] == 123 and loaded.hidden == (32, 32)
    obs = rng.normal(2.0, 3.0, size=(64, 4))
    a1, a2 = expert(obs), loaded(obs)
    assert a1.shape == (64, 1) and np.array_equal(a1, a2) and np.abs(a1).max() <= 1.0
    assert np.array_equal(loaded(obs[0]), a1[0])
    # the expert's action is the learner's deterministic action on the frozen-normalized observation
    with torch.no_grad():
        ref = agent.policy.deterministic(torch.from_numpy(agent.normalize(obs))).clamp(-1, 1).double().numpy()
    assert np.array_equal(a1, ref)
    # different weights, different checksum
    with torch.no_grad():
        loaded.policy.log_std.add_(0.1)
    assert loaded.checksum() != checksum


def test_eval_function_reproducible():
    envs = make_vec_env(TASK, 2, False)
    from loco_il.experts.vec import evaluate
    zero = lambda obs: np.zeros((len(obs), 1))  # noqa: E731
    r1, l1 = evaluate(zero, envs, 3, seed=5)
    r2, l2 = evaluate(zero, envs, 3, seed=5)
    envs.close()
    assert len(r1) == 3 and np.array_equal(r1, r2) and np.array_equal(l1, l2)


def test_evaluate_episodes_tells_falls_from_time_limits():
    from loco_il.experts.vec import evaluate_episodes
    push = lambda obs: np.ones((len(obs), 1))  # noqa: E731   (full force: the pole falls within a few steps)
    envs = make_vec_env(TASK, 2, False)
    _, lengths, terminated = evaluate_episodes(push, envs, 3, seed=0)
    envs.close()
    assert terminated.all() and (lengths < 1000).all()
    zero = lambda obs: np.zeros((len(obs), 1))  # noqa: E731
    short = make_vec_env(TASK, 1, False, env_kwargs={"horizon": 3})    # truncated before the pole can fall
    _, lengths, terminated = evaluate_episodes(zero, short, 2, seed=0)
    short.close()
    assert not terminated.any() and (lengths == 3).all()


# ---------------------------------------------------------------------------- CLI
@pytest.mark.slow
def test_cli_train_and_eval(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = tmp_path / "tmp"
    cmd = [sys.executable, "-m", "loco_il.experts", "train", "task=InvertedPendulum.balance", "total_steps=2048",
           "num_envs=2", f"out_dir={out}", "async=false"]
    proc = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["env_steps"] >= 2048 and "eval_return_mean" in summary and "wall_time_s" in summary
    assert (out / "checkpoint.pt").exists() and (out / "best.pt").exists()
    assert sorted(p.name for p in (out / "snapshots").iterdir())[0] == "step_000000000.pt"
    proc = subprocess.run([sys.executable, "-m", "loco_il.experts", "eval", f"path={out / 'best.pt'}",
                           "episodes=2"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert result["episodes"] == 2 and result["task_id"] == TASK
    # a folder: every policy on the same episodes, then the most reliable (fewest terminated, then best mean)
    proc = subprocess.run([sys.executable, "-m", "loco_il.experts", "eval", f"path={out / 'snapshots'}",
                           "episodes=2"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    *lines, last = [json.loads(line) for line in proc.stdout.strip().splitlines()]
    assert [Path(r["path"]).name for r in lines] == sorted(p.name for p in (out / "snapshots").iterdir())
    untrained = lines[0]
    assert untrained["training_steps"] == 0 and untrained["terminated"] == 2 and untrained["length_mean"] < 1000
    best = min(lines, key=lambda r: (r["terminated"], -r["return_mean"]))
    assert last["most_reliable"] == best["path"] and last["evaluated"] == len(lines)


def test_per_body_config_sits_between_train_yaml_and_command_line():
    from hydra import compose, initialize_config_dir

    from loco_il.experts.__main__ import CONFIG_DIR, compose_train_config
    overrides = ["task=InvertedPendulum.balance", "lr=5e-4"]
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base=None):
        cfg = compose(config_name="train", overrides=overrides)
    plain = compose_train_config(cfg, overrides)
    assert plain["lr"] == 5e-4                 # command line beats configs/body/InvertedPendulum.yaml
    assert plain["num_steps"] == 256           # the body file beats train.yaml (128)
    assert plain["out_dir"] == "runs/experts/InvertedPendulum.balance/seed0"
    TrainConfig.from_mapping(plain)
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base=None):
        hopper = compose_train_config(compose(config_name="train", overrides=["task=Hopper.run"]), ["task=Hopper.run"])
    assert hopper["num_steps"] is None and hopper["lr"] == 3e-4
    assert TrainConfig.from_mapping(hopper).steps_per_env == 128               # 2048 / 16 envs
    assert TrainConfig.from_mapping(dict(hopper, num_envs=2)).steps_per_env == 1024


def test_a_resumed_run_takes_the_learning_rate_of_its_new_config(tmp_path):
    out = tmp_path / "run"
    PPOTrainer(small_cfg(out, total_steps=1024, lr=1e-3, lr_decay=False), log=quiet).train()
    resumed = PPOTrainer(small_cfg(out, total_steps=1536, lr=2e-4, lr_decay=False), log=quiet)
    resumed.train()
    assert {g["lr"] for g in resumed.agent.pi_opt.param_groups} == {2e-4}
