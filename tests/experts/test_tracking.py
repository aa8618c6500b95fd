"""Motion-tracking experts: the reference, the DeepMimic reward, reference state initialization, the PD
conversion, the expert file and the trainer (loco_il.experts.tracking)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from loco_il import LocoEnv
from loco_il.experts.tracking.controller import PHASE_FEATURES, TrackingController
from loco_il.experts.tracking.env import TrackingEnv
from loco_il.experts.tracking.reference import build_reference
from loco_il.experts.tracking.reward import TrackingReward
from loco_il.experts.tracking.settings import TrackingSettings

TASK = "Atlas.walk.perfect"


@pytest.fixture(scope="module")
def env():
    e = LocoEnv.make(TASK)
    yield e
    e.stop()


@pytest.fixture(scope="module")
def reference(env):
    return build_reference(env, target_speed=1.25)


def _anchor(env, reward, reference, phase):
    return env.data.xpos[reward.root][:2] - reference.kinematics(phase)[0][:2]


def test_reference_is_periodic_with_drift_and_time_scaled(env, reference):
    assert reference.speed == pytest.approx(1.25, rel=1e-6)        # time-scaled to the walk task's target
    assert reference.time_scale > 1.0                               # the captured walk is slower (~1.0 m/s)
    for phase in (0.0, 0.37, 0.999):
        q0, v0 = reference.state(phase)
        q1, v1 = reference.state(phase + 1.0)
        np.testing.assert_allclose(q1 - q0, reference.drift, atol=1e-12)
        np.testing.assert_allclose(v1, v0, atol=1e-12)
    assert reference.drift[0] > 1.0 and np.count_nonzero(reference.drift) <= 2   # one stride along x only
    # velocities are the positions' time derivative (central difference over one control step)
    h = env.dt / reference.period
    q_minus, _ = reference.state(0.5 - h)
    q_plus, _ = reference.state(0.5 + h)
    _, v = reference.state(0.5)
    np.testing.assert_allclose(v, (q_plus - q_minus) / (2 * env.dt), atol=0.05 * np.abs(v).max())


def test_tracking_reward_is_one_on_the_reference_and_falls_with_error(env, reference):
    settings = TrackingSettings()
    reward = TrackingReward(env.model, reference, settings)
    for phase in (0.1, 0.6, 1.3):
        q, v = reference.state(phase)
        env.reset(np.concatenate([q, v]))
        r, terms = reward(env.data, phase, np.zeros(2))
        assert r == pytest.approx(1.0, abs=1e-6)
        assert terms["root_error"] < 1e-9
    q, v = reference.state(0.25)
    previous = 1.0
    rng = np.random.default_rng(0)
    direction = rng.standard_normal(reference.actuated_qpos.size)
    for size in (0.02, 0.05, 0.1, 0.2, 0.4):       # larger joint errors, lower reward
        bent = q.copy()
        bent[reference.actuated_qpos] += size * direction
        env.reset(np.concatenate([bent, v]))
        r, terms = reward(env.data, 0.25, np.zeros(2))
        assert r < previous
        previous = r
    # a lagging root costs through the root term only
    shifted = q.copy()
    shifted[0] -= 0.3
    env.reset(np.concatenate([shifted, v]))
    r, terms = reward(env.data, 0.25, np.zeros(2))
    assert terms["root_error"] == pytest.approx(0.3, abs=1e-6)
    assert terms["pose"] == pytest.approx(1.0, abs=1e-6) and terms["root"] == pytest.approx(np.exp(-10 * 0.09))


def test_reference_state_initialization_starts_on_the_reference(env, reference):
    settings = TrackingSettings(rsi_fraction=1.0, rsi_noise=0.0)
    controller = TrackingController.for_model(env.model, reference, settings, env.dt)
    tenv = TrackingEnv(TASK, controller.to_dict(), "train")
    phases = []
    for seed in range(4):
        obs, _ = tenv.reset(seed=seed)
        phase = tenv.controller.phase
        phases.append(phase)
        q, v = reference.state(phase)
        np.testing.assert_allclose(tenv.loco_env.data.qpos, q, atol=1e-12)
        np.testing.assert_allclose(tenv.loco_env.data.qvel, v, atol=1e-12)
        assert obs.shape == (tenv.loco_env.obs_spec.dim + PHASE_FEATURES,)
        np.testing.assert_allclose(obs[-2:], [np.sin(2 * np.pi * phase), np.cos(2 * np.pi * phase)])
        _, r, *_ = tenv.step(np.zeros(env.model.nu))
        assert 0.0 < r <= 1.0
    assert len(set(np.round(phases, 6))) == 4                       # seeded, distinct phases
    tenv.close()


def test_eval_mode_starts_from_the_env_and_pays_the_task_reward(env, reference):
    controller = TrackingController.for_model(env.model, reference, TrackingSettings(), env.dt)
    tenv = TrackingEnv(TASK, controller.to_dict(), "eval")
    tenv.reset(seed=0)
    plain = LocoEnv.make(TASK)
    plain.seed(0)
    plain.reset()
    np.testing.assert_allclose(tenv.loco_env.data.qpos, plain.data.qpos)      # the env's own (noisy) start
    assert tenv.controller.phase == reference.nearest_phase(plain.data.qpos)
    _, r, _, _, info = tenv.step(np.zeros(env.model.nu))
    assert r == pytest.approx(np.exp(-(info["reward_terms"]["x_velocity"] - 1.25) ** 2))
    plain.stop()
    tenv.close()


def test_stable_pd_follows_the_reference_better_than_no_control(env, reference):
    """Zero policy action = PD toward the reference: from RSI the robot stays up longer than with zero torque."""
    settings = TrackingSettings(rsi_fraction=1.0, rsi_noise=0.0)
    controller = TrackingController.for_model(env.model, reference, settings, env.dt)
    assert (controller.kp > 0).all() and (controller.kd > 0).all()   # Atlas: torque motors
    tenv = TrackingEnv(TASK, controller.to_dict(), "train")
    tracked, limp = [], []
    for seed in range(3):
        tenv.reset(seed=seed)
        state = np.concatenate(tenv.loco_env.get_sim_state())
        for lengths, act in ((tracked, lambda: tenv.step(np.zeros(env.model.nu))),
                             (limp, lambda: tenv.loco_env.step(np.zeros(env.model.nu)))):
            tenv.reset(seed=seed)
            n = 0
            while n < 300:
                out = act()
                n += 1
                if out[2]:
                    break
            lengths.append(n)
        assert np.isfinite(state).all()
    assert np.mean(tracked) > np.mean(limp)
    tenv.close()


def test_clock_ramp_starts_the_reference_at_the_bodys_own_speed(env, reference):
    """From standing the phase clock starts near rate 0 and reaches full rate after clock_ramp_time; from a
    reference state it runs at full rate at once; clock_ramp_time=0 keeps the full rate from the start."""
    steps = int(round(1.0 / env.dt))
    advance = {}
    for ramp in (0.0, 1.0):
        controller = TrackingController.for_model(env.model, reference, TrackingSettings(clock_ramp_time=ramp), env.dt)
        env.seed(0)
        env.reset()
        controller.start(0.0, env.data)
        rates = []
        for _ in range(steps + 5):
            controller.env_action(np.zeros(env.model.nu), env.model, env.data)
            rates.append(controller.rate)
        advance[ramp] = controller.phase
        if ramp == 0.0:
            assert rates == [1.0] * len(rates)
        else:
            assert rates[0] < 0.05 and np.all(np.diff(rates) >= 0) and rates[steps - 1] == 1.0
        q, v = reference.state(0.3)
        env.reset(np.concatenate([q, v]))
        controller.start(0.3, env.data)
        assert controller.rate > 0.5                               # on the reference: (nearly) full speed
    assert advance[0.0] == pytest.approx((steps + 5) * env.dt / reference.period)
    assert advance[1.0] < advance[0.0] - 0.4 * env.dt * steps / reference.period   # ~half a second of phase lost


def test_clock_ramp_enters_the_checksum_only_when_used(env, reference):
    digests = [TrackingController.for_model(env.model, reference, TrackingSettings(clock_ramp_time=t), env.dt)
               .digest_bytes() for t in (0.0, 0.0, 1.0)]
    assert digests[0] == digests[1] != digests[2]
    assert "clock_ramp_time" not in dict(TrackingSettings().digest_items())


def test_speed_gain_speeds_the_clock_up_slowly_and_is_a_deployment_setting(env, reference):
    """speed_gain multiplies the clock's rate, reached from 1 over speed_gain_time; with_settings derives an
    expert with another gain (a new checksum naming its source), and refuses settings that need retraining."""
    from loco_il.experts.policy import ExpertPolicy
    from loco_il.experts.tracking.expert import TrackingExpert
    settings = TrackingSettings(speed_gain=1.05, speed_gain_time=2.0)
    controller = TrackingController.for_model(env.model, reference, settings, env.dt)
    env.seed(0)
    env.reset()
    controller.start(0.0, env.data)
    rates = []
    for _ in range(int(round(2.5 / env.dt))):
        controller.env_action(np.zeros(env.model.nu), env.model, env.data)
        rates.append(controller.rate)
    assert rates[0] == pytest.approx(1.0, abs=1e-4) and np.all(np.diff(rates) >= 0) and rates[-1] == 1.05
    assert rates[int(round(0.5 / env.dt))] < 1.01                 # the first half second is (nearly) untouched

    policy = ExpertPolicy(env.info.observation_space.shape[0] + PHASE_FEATURES, env.model.nu, hidden=(8,))
    base = TrackingExpert(policy, TrackingController.for_model(env.model, reference, TrackingSettings(), env.dt))
    tuned = base.with_settings(speed_gain=1.04, speed_gain_time=4)
    assert tuned.controller.settings.speed_gain == 1.04 and base.controller.settings.speed_gain == 1.0
    assert tuned.checksum() != base.checksum() and tuned.metadata["derived_from"]["checksum"] == base.checksum()
    with pytest.raises(ValueError, match="kp_angle.*retrain"):
        base.with_settings(kp_angle=0.5)


def test_start_phase_picks_one_of_the_two_phases_a_standing_pose_matches(env, reference):
    """A noisy standing pose is about as near the two double-support phases (half a period apart): the nearest
    phase alternates between them with the reset noise, `start_phase` fixes one; reference poses keep their own
    phase whatever is preferred, and the setting is a deployment one (None: not in the checksum)."""
    from loco_il.experts.policy import ExpertPolicy
    from loco_il.experts.tracking.expert import TrackingExpert
    nearest, preferred = [], {0.45: [], 0.95: []}
    for seed in range(20):
        env.seed(seed)
        env.reset()
        nearest.append(reference.nearest_phase(env.data.qpos))
        for prefer, got in preferred.items():
            got.append(reference.nearest_phase(env.data.qpos, prefer=prefer))
    first, second = min(nearest), max(nearest)
    assert second - first == pytest.approx(0.5, abs=0.05)
    assert sum(abs(p - first) < 0.03 for p in nearest) >= 3 and sum(abs(p - second) < 0.03 for p in nearest) >= 3
    assert max(abs(np.array(preferred[0.45]) - first)) < 0.03 and max(abs(np.array(preferred[0.95]) - second)) < 0.03
    for k in range(0, reference.samples, 7):
        assert reference.nearest_phase(reference.qpos[k], prefer=(k / reference.samples + 0.5) % 1.0) \
            == k / reference.samples

    controller = TrackingController.for_model(env.model, reference, TrackingSettings(start_phase=0.95), env.dt)
    assert controller.start_phase_of(env.data.qpos) == preferred[0.95][-1]
    assert "start_phase" not in dict(TrackingSettings().digest_items())
    policy = ExpertPolicy(env.info.observation_space.shape[0] + PHASE_FEATURES, env.model.nu, hidden=(8,))
    base = TrackingExpert(policy, TrackingController.for_model(env.model, reference, TrackingSettings(), env.dt))
    tuned = base.with_settings(start_phase=0.95)
    assert tuned.controller.start_phase_of(env.data.qpos) == preferred[0.95][-1]
    assert tuned.checksum() != base.checksum()
    assert base.with_settings(start_phase=None).checksum() == base.checksum()
    with pytest.raises(ValueError, match="start_phase must be a phase in"):
        base.with_settings(start_phase=1.5)
    with pytest.raises(ValueError, match="start_phase must be a phase in"):
        TrackingSettings(start_phase=1.0)                     # a training run's setting is checked as well
    with pytest.raises(ValueError, match="deployment settings are numbers"):
        base.with_settings(speed_gain=None)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny tracking run (2 iterations): files, resume and the shipped expert's format."""
    from loco_il.experts.tracking.trainer import TrackingTrainer
    out = tmp_path_factory.mktemp("tracking")
    cfg = {"task": "Atlas.walk", "algo": "tracking", "total_steps": 1024, "num_envs": 2, "async": False,
           "batch_size": 512, "minibatch_size": 256, "epochs": 1, "hidden": [32, 32], "activation": "elu",
           "eval_interval": 512, "eval_episodes": 2, "snapshot_every": 0.5, "out_dir": str(out), "log_interval_s": 0}
    summary = TrackingTrainer(dict(cfg)).train()
    return out, cfg, summary


def test_trainer_writes_tracking_experts_and_resumes(trained):
    from loco_il.experts.policy import load_expert
    from loco_il.experts.tracking.expert import TrackingExpert
    from loco_il.experts.tracking.trainer import TrackingTrainer
    out, cfg, summary = trained
    assert summary["env_steps"] == 1024
    best = load_expert(out / "best.pt")
    assert isinstance(best, TrackingExpert) and best.obs_dim == 30 and best.act_dim == 10
    assert len(list((out / "snapshots").glob("step_*.pt"))) >= 2
    rows = [json.loads(line) for line in (out / "evals.jsonl").read_text().splitlines()]
    assert all("terminated" in row for row in rows)
    with pytest.raises(ValueError, match="tracking.action_scale was 0.5, now 0.3"):
        TrackingTrainer(dict(cfg, total_steps=1536, tracking={"action_scale": 0.3}))
    resumed = TrackingTrainer(dict(cfg, total_steps=1536, tracking={"rsi_fraction": 0.5}))   # training-only: may change
    assert resumed.step == 1024 and resumed.controller.settings.rsi_fraction == 0.5
    np.testing.assert_array_equal(resumed.controller.reference.qpos, best.controller.reference.qpos)
    assert resumed.train()["env_steps"] == 1536


def test_a_run_can_start_from_another_runs_networks_with_other_expert_settings(trained, tmp_path):
    import torch
    from loco_il.experts.tracking.trainer import TrackingTrainer
    out, cfg, _ = trained
    fresh = dict(cfg, out_dir=str(tmp_path / "warm"), init_from=str(out / "checkpoint.pt"),
                 tracking={"clock_ramp_time": 1.0})
    warm = TrackingTrainer(fresh)
    source = torch.load(out / "checkpoint.pt", weights_only=True)["agent"]
    state = warm.learner_state()
    assert warm.step == 0 and warm.controller.settings.clock_ramp_time == 1.0
    for part in ("policy", "value", "obs_rms"):
        assert source[part].keys() == state[part].keys() and len(source[part]) > 0
        for name, value in source[part].items():
            assert np.array_equal(np.asarray(state[part][name]), np.asarray(value)), (part, name)
    cold = TrackingTrainer(dict(cfg, out_dir=str(tmp_path / "cold"))).learner_state()     # same seed, no init_from
    assert not np.array_equal(np.asarray(state["policy"]["net.0.weight"]), np.asarray(cold["policy"]["net.0.weight"]))
    assert warm.metadata(None)["init_from"] == str(out / "checkpoint.pt")
    with pytest.raises(ValueError, match="no such file"):
        TrackingTrainer(dict(fresh, out_dir=str(tmp_path / "bad"), init_from=str(tmp_path / "missing.pt")))
    with pytest.raises(ValueError, match="hidden"):
        TrackingTrainer(dict(fresh, out_dir=str(tmp_path / "bad2"), hidden=[16, 16]))


def test_tracking_expert_file_round_trip_and_env_level_use(trained, tmp_path):
    from loco_il.experts.policy import load_expert
    out, _, _ = trained
    expert = load_expert(out / "final.pt")
    copy = tmp_path / "copy.pt"
    assert expert.save(copy) == expert.checksum()
    again = load_expert(copy)
    assert again.checksum() == expert.checksum()
    env = LocoEnv.make(TASK)
    actions = []
    for e in (expert, again):
        env.seed(3)
        obs = env.reset()
        e.start_episode(env, 3)
        actions.append(e(obs))
    np.testing.assert_array_equal(actions[0], actions[1])
    assert np.all(np.abs(actions[0]) <= 1.0)
    with pytest.raises(RuntimeError, match="start_episode"):
        load_expert(copy)(obs)
    # a changed reference changes the checksum (it is part of the datasets' cache key)
    data = __import__("torch").load(copy, weights_only=True)
    data["controller"]["kp"] = data["controller"]["kp"] * 2
    __import__("torch").save(data, tmp_path / "tampered.pt")
    with pytest.raises(ValueError, match="checksum mismatch"):
        load_expert(tmp_path / "tampered.pt")
    env.stop()


def test_tracking_expert_records_a_replayable_perfect_dataset(trained, tmp_path, monkeypatch):
    """The provider replays the first recorded episode from its start state and fails on any difference."""
    out, _, _ = trained
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path))
    env = LocoEnv.make(TASK)
    data = env.create_dataset(expert_path=str(out / "final.pt"), n_episodes=2, verbose=False)
    assert data.n_trajectories == 2 and data.actions.shape[1] == 10
    assert np.abs(data.actions).max() <= 1.0
    env.stop()


@pytest.mark.slow
def test_train_py_imitates_a_tracking_expert_on_atlas(trained, tmp_path):
    """The mission's command on a robot: `train.py task=Atlas.walk.perfect algo=lsiq`, its `perfect` dataset
    generated from a tracking expert (here the tiny one above, installed through $LOCO_IL_EXPERTS)."""
    import os
    import shutil
    import subprocess
    import sys
    from pathlib import Path
    out, _, _ = trained
    experts = tmp_path / "experts" / "Atlas.walk"
    experts.mkdir(parents=True)
    shutil.copy(out / "final.pt", experts / "expert.pt")
    env = dict(os.environ, LOCO_IL_EXPERTS=str(tmp_path / "experts"), LOCO_IL_DATASETS=str(tmp_path / "datasets"),
               WANDB_MODE="offline", OMP_NUM_THREADS="1")
    root = Path(__file__).resolve().parents[2]
    cmd = [sys.executable, "train.py", "task=Atlas.walk.perfect", "algo=lsiq", "n_steps=300", "eval.every=300",
           f"results_dir={tmp_path / 'results'}", "dataset.n_episodes=2", "eval=quick", "logger=csv",
           "algo.policy.hidden=[32,32]", "algo.params.critic_hidden=[32,32]", "algo.params.initial_replay_size=100",
           "algo.params.batch_size=32", "algo.params.expert_batch_size=32", "hydra/job_logging=disabled"]
    proc = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    run = tmp_path / "results" / "Atlas.walk.perfect" / "lsiq" / "seed0"
    final = json.loads((run / "eval.json").read_text())
    assert final["steps"] == 300 and final["task_id"] == "Atlas.walk.perfect"
    assert list((tmp_path / "datasets" / "Atlas.walk").glob("perfect-n2-*.npz"))


def test_the_config_file_lists_every_tracking_option_at_its_default():
    """`tracking.<name>=<value>` on the command line needs the key in the config (Hydra's struct mode)."""
    import dataclasses
    from pathlib import Path

    import yaml
    path = Path(__file__).resolve().parents[2] / "loco_il" / "experts" / "configs" / "algo" / "tracking.yaml"
    listed = yaml.safe_load(path.read_text())["tracking"]
    assert listed == {f.name: f.default for f in dataclasses.fields(TrackingSettings)}
