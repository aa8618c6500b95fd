"""SAC expert trainer: the soft Bellman target, replay bookkeeping, resume (with and without the replay
memory), squashed expert files, and learning on InvertedPendulum."""
from __future__ import annotations

import copy
import json
import shutil

import numpy as np
import pytest
import torch

from loco_il.rl.networks import GaussianPolicy
from loco_il.datasets.baselines import load_baselines
from loco_il.experts import load_expert
from loco_il.experts.sac import SACTrainer, init_actor_output, soft_td_target, twin_critic_loss

TASK = "InvertedPendulum.balance.perfect"


def small_cfg(out_dir, **kw) -> dict:
    cfg = dict(algo="sac", task=TASK, out_dir=str(out_dir), total_steps=300, random_steps=100, learning_starts=100,
               batch_size=32, hidden=(32, 32), eval_interval=0, eval_episodes=2, snapshot_every=0,
               log_interval_s=1000, checkpoint_minutes=100, device="cpu", async_envs=False, seed=0)
    cfg.update(kw)
    return cfg


def quiet(_msg: str) -> None:
    pass


def test_soft_td_target_and_twin_loss_hand_computed():
    r = torch.tensor([1.0, 2.0])
    absorbing = torch.tensor([0.0, 1.0])
    next_v = torch.tensor([10.0, 10.0])
    y = soft_td_target(r, absorbing, next_v, gamma=0.9)
    torch.testing.assert_close(y, torch.tensor([10.0, 2.0]))          # 1 + 0.9 * 10; absorbing: r only
    loss = twin_critic_loss(torch.tensor([9.0, 2.0]), torch.tensor([10.0, 4.0]), y)
    torch.testing.assert_close(loss, torch.tensor(0.5 + 2.0))         # mean(1, 0) + mean(0, 4)


def test_replay_counts_updates_and_resume_with_replay(tmp_path):
    tr = SACTrainer(small_cfg(tmp_path), log=quiet)
    summary = tr.train()
    assert summary["env_steps"] == 300 and len(tr.replay) == 300
    assert tr.n_updates == 201      # one per env step from the step that stores the 100th transition
    assert torch.isfinite(tr.replay.rewards[:300]).all() and tr.replay.rewards[:300].min() >= 0.0
    ab = tr.replay.absorbing[:300]
    assert 0 < ab.sum() < 300                       # falls are absorbing, nothing else
    resumed = SACTrainer(small_cfg(tmp_path, total_steps=400), log=quiet)
    assert resumed.resumed_from == 300 and len(resumed.replay) == 300 and resumed.n_updates == 201
    resumed.train()
    assert len(resumed.replay) == 400 and resumed.n_updates == 301


def test_resume_without_replay_refills_before_updating(tmp_path):
    SACTrainer(small_cfg(tmp_path, checkpoint_replay=False), log=quiet).train()
    messages: list[str] = []
    tr = SACTrainer(small_cfg(tmp_path, checkpoint_replay=False, total_steps=450), log=messages.append)
    assert len(tr.replay) == 0 and any("no replay memory" in m for m in messages)
    tr.train()
    assert len(tr.replay) == 150 and tr.n_updates == 201 + 51   # updates resume at 100 stored transitions


def test_refill_from_policy_files_splits_the_refill_among_them(tmp_path):
    run, kept = tmp_path / "run", tmp_path / "kept"
    SACTrainer(small_cfg(run, checkpoint_replay=False), log=quiet).train()
    files = [kept / "step_000000001.pt", kept / "step_000000002.pt"]
    for seed, file in enumerate(files):         # two different policies
        SACTrainer(small_cfg(tmp_path / f"other{seed}", seed=seed + 1), log=quiet).make_expert().save(file)
    messages: list[str] = []
    tr = SACTrainer(small_cfg(run, checkpoint_replay=False, total_steps=450, learning_starts=100,
                              refill_from=str(kept)), log=messages.append)
    assert any("2 policies of" in m for m in messages)
    tr.start()

    def store(n: int) -> None:                 # n placeholder transitions
        zeros = np.zeros((n, tr.obs_dim))
        tr.replay.add(zeros, zeros, np.zeros(n), np.zeros((n, tr.act_dim)), np.zeros(n))

    for share in (0, 1):                       # the first 50 refill steps by the first file, then 50 by the second
        rng = copy.deepcopy(tr.rng)
        expected = load_expert(files[share]).act(tr._obs, deterministic=False, rng=rng)
        np.testing.assert_allclose(tr._actions(), expected, rtol=1e-6)
        store(50)
    with torch.no_grad():                      # refilled: the current policy acts again
        torch.manual_seed(0)
        expected = tr.policy.sample(torch.as_tensor(tr._obs, dtype=torch.float32))[0].numpy()
        torch.manual_seed(0)
        np.testing.assert_allclose(tr._actions(), expected)
    with pytest.raises(FileNotFoundError, match="no policy files"):
        SACTrainer(small_cfg(run, checkpoint_replay=False, refill_from=str(tmp_path)), log=quiet)


def test_slim_checkpoint_drops_the_replay_and_resumes(tmp_path, capsys):
    from loco_il.experts.__main__ import main
    run, moved = tmp_path / "run", tmp_path / "moved"
    SACTrainer(small_cfg(run), log=quiet).train()
    moved.mkdir()
    main(["slim", f"path={run / 'checkpoint.pt'}", f"out={moved / 'checkpoint.pt'}"])
    info = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert info["step"] == 300 and info["bytes_after"] < info["bytes_before"]
    messages: list[str] = []
    tr = SACTrainer(small_cfg(moved, total_steps=450), log=messages.append)
    assert tr.resumed_from == 300 and tr.n_updates == 201 and len(tr.replay) == 0
    assert any("no replay memory" in m for m in messages)
    torch.testing.assert_close(tr.policy.state_dict(), SACTrainer(small_cfg(run), log=quiet).policy.state_dict())


def test_resume_drops_evaluations_logged_after_the_checkpoint(tmp_path):
    SACTrainer(small_cfg(tmp_path, eval_interval=100, keep_eval_policies=True), log=quiet).train()
    log = tmp_path / "evals.jsonl"
    steps = [json.loads(line)["step"] for line in log.read_text().splitlines()]
    assert steps[-1] == 300
    # a killed run evaluated at step 350 after its last checkpoint (300): that step will be re-run
    with open(log, "a") as f:
        f.write(json.dumps({"step": 350, "return_mean": 1.0}) + "\n")
    shutil.copy(tmp_path / "evals" / "step_000000300.pt", tmp_path / "evals" / "step_000000350.pt")
    tr = SACTrainer(small_cfg(tmp_path, eval_interval=100, total_steps=400, keep_eval_policies=True), log=quiet)
    assert [json.loads(line)["step"] for line in log.read_text().splitlines()] == steps
    assert sorted(p.name for p in (tmp_path / "evals").glob("*.pt")) == [f"step_{s:09d}.pt" for s in steps]
    tr.train()
    after = [json.loads(line)["step"] for line in log.read_text().splitlines()]
    assert after[:len(steps)] == steps and after[len(steps):] == [400]


def test_expert_file_is_the_squashed_deterministic_policy(tmp_path):
    tr = SACTrainer(small_cfg(tmp_path, total_steps=200), log=quiet)
    tr.train()
    expert = load_expert(tmp_path / "final.pt")
    assert expert.squash and expert.metadata["algorithm"] == "SAC" and expert.metadata["squash"] is True
    obs = np.random.default_rng(0).normal(size=(16, 4))
    with torch.no_grad():
        ref = torch.tanh(tr.policy.net(torch.as_tensor(obs, dtype=torch.float32)).chunk(2, -1)[0]).double().numpy()
    np.testing.assert_allclose(expert(obs), ref, atol=1e-6)
    noisy = expert.act(obs, deterministic=False, rng=np.random.default_rng(1))
    assert np.abs(noisy).max() < 1.0 and not np.allclose(noisy, expert(obs))
    np.testing.assert_array_equal(noisy, expert.act(obs, deterministic=False, rng=np.random.default_rng(1)))


@pytest.mark.slow
def test_sac_learns_inverted_pendulum(tmp_path):
    random_return = load_baselines()["InvertedPendulum.balance"]["random"]["return_mean"]
    cfg = small_cfg(tmp_path, total_steps=3000, random_steps=500, learning_starts=500, batch_size=256,
                    hidden=(256, 256), eval_interval=1000, eval_episodes=5)
    summary = SACTrainer(cfg, log=quiet).train()
    assert summary["best_eval_return"] >= 5 * random_return, (summary, random_return)


@pytest.mark.slow
def test_keep_eval_policies_saves_every_evaluated_policy(tmp_path):
    # SAC iterates ~1000 env steps at a time: 2100 steps with eval_interval 1000 evaluate at 1000, 2000, 2100
    SACTrainer(small_cfg(tmp_path, total_steps=2100, hidden=(8, 8), eval_interval=1000, keep_eval_policies=True),
               log=quiet).train()
    files = sorted(p.name for p in (tmp_path / "evals").glob("step_*.pt"))
    evals = [json.loads(line) for line in (tmp_path / "evals.jsonl").read_text().splitlines()]
    assert files == [f"step_{ev['step']:09d}.pt" for ev in evals] and len(files) >= 3
    last = load_expert(tmp_path / "evals" / files[-1])
    assert last.metadata["training_steps"] == evals[-1]["step"]
    assert last.metadata["eval_return"] == evals[-1]["return_mean"]
    SACTrainer(small_cfg(tmp_path / "off"), log=quiet).train()
    assert not (tmp_path / "off" / "evals").exists()          # off by default


def test_init_actor_output_sets_mean_and_spread_for_any_observation():
    torch.manual_seed(0)
    policy = GaussianPolicy(5, 3, (16, 16), squash=True)
    target = np.array([0.5, -0.2, 0.99])           # 0.99 is clipped to 0.97 so that atanh stays finite
    init_actor_output(policy, target, log_std=-3.0)
    obs = torch.randn(64, 5)
    mean, log_std = policy._mean_log_std(obs)
    np.testing.assert_allclose(torch.tanh(mean).detach().numpy(), np.tile([0.5, -0.2, 0.97], (64, 1)), atol=0.02)
    np.testing.assert_allclose(log_std.detach().numpy(), -3.0, atol=0.05)
    torch.manual_seed(0)
    untouched = GaussianPolicy(5, 3, (16, 16), squash=True)
    init_actor_output(untouched, target, log_std=None)              # the log-std half keeps its initialization
    torch.manual_seed(0)
    fresh = GaussianPolicy(5, 3, (16, 16), squash=True)
    torch.testing.assert_close(untouched._mean_log_std(obs)[1], fresh._mean_log_std(obs)[1])


def test_init_action_home_starts_from_the_standing_servo_targets(tmp_path):
    tr = SACTrainer(small_cfg(tmp_path, task="BoosterT1.walk", init_action="home", init_log_std=-3.0), log=quiet)
    home = np.asarray(tr.body_extra["home_action"])
    assert np.abs(home).max() > 0.1
    expert = tr.make_expert()
    obs = np.random.default_rng(0).normal(size=(8, tr.obs_dim))
    np.testing.assert_allclose(expert(obs), np.tile(np.clip(home, -0.97, 0.97), (8, 1)), atol=0.05)
    default = SACTrainer(small_cfg(tmp_path / "zero", task="BoosterT1.walk"), log=quiet)
    assert np.abs(default.make_expert()(obs)).max() < 0.5           # the default init stays near zero
    with pytest.raises(ValueError, match="no home action"):
        SACTrainer(small_cfg(tmp_path / "pendulum", init_action="home"), log=quiet)
    with pytest.raises(ValueError, match="init_action='stand'"):
        SACTrainer(small_cfg(tmp_path / "typo", init_action="stand"), log=quiet)


def test_alive_bonus_shapes_training_rewards_only(tmp_path):
    base = SACTrainer(small_cfg(tmp_path / "base", total_steps=120), log=quiet)
    base.train()
    shaped = SACTrainer(small_cfg(tmp_path / "shaped", total_steps=120, alive_bonus=0.5), log=quiet)
    shaped.train()
    # the first 100 steps take the same seeded random actions in both runs
    torch.testing.assert_close(shaped.replay.rewards[:100], base.replay.rewards[:100] + 0.5)
    # logged episode returns are the env's (InvertedPendulum: 1 per step alive, 0 on the falling step)
    assert all(ret <= length for ret, length in shaped.recent)
    assert shaped.recent[0] == base.recent[0]        # the first episode ends during the random steps


def test_backup_entropy_false_drops_the_entropy_term_from_the_critic_target(tmp_path, monkeypatch):
    seen: list[bool] = []
    tr = SACTrainer(small_cfg(tmp_path, total_steps=110, backup_entropy=False), log=quiet)
    original = tr.sac.target_soft_value
    monkeypatch.setattr(tr.sac, "target_soft_value",
                        lambda obs, with_entropy=True: seen.append(with_entropy) or original(obs, with_entropy))
    tr.train()
    assert len(seen) == tr.n_updates > 0 and not any(seen)


def test_value_bounds_clip_the_bootstrapped_value(tmp_path, monkeypatch):
    import loco_il.experts.sac as sac_module
    seen: list[torch.Tensor] = []
    real_target = sac_module.soft_td_target
    monkeypatch.setattr(sac_module, "soft_td_target",
                        lambda r, ab, next_v, gamma: seen.append(next_v) or real_target(r, ab, next_v, gamma))
    tr = SACTrainer(small_cfg(tmp_path, total_steps=110, value_bounds=[-1.0, 5.0]), log=quiet)
    monkeypatch.setattr(tr.sac, "target_soft_value",
                        lambda obs, with_entropy=True: torch.linspace(-1e3, 1e3, obs.shape[0]))
    tr.train()
    assert len(seen) == tr.n_updates > 0
    assert all(v.min() == -1.0 and v.max() == 5.0 for v in seen)
    with pytest.raises(ValueError, match="lo < hi"):
        SACTrainer(small_cfg(tmp_path / "bad", value_bounds=[5.0, -1.0]), log=quiet)
