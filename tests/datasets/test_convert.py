"""Tests of loco_il.datasets.convert: Minari round trip and LocoMuJoCo .npz loading."""

from __future__ import annotations

import numpy as np
import pytest

from loco_il.datasets import DatasetError, Trajectories
from loco_il.datasets.convert import from_minari, load_locomujoco_npz, to_minari

from dataset_factories import assert_same, make_dataset


def make_rollouts(lengths=(5, 3, 7), obs_dim=4, act_dim=2, seed=0, actions=True):
    """Float32 actions like most recorded policies; episode 1 ends absorbing."""
    return make_dataset(lengths, obs_dim, act_dim, actions=actions, seed=seed, action_dtype=np.float32)


# ----------------------------------------------------------------------------- minari


@pytest.fixture
def minari_dir(tmp_path, monkeypatch):
    # minari[hdf5] is a test dependency (pyproject [test]); a missing install must fail, not skip
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    return tmp_path / "minari"


def test_minari_round_trip(minari_dir):
    data = make_rollouts()
    ds = to_minari(data, "loco_il_test/hopper-run-v0")
    assert ds.total_episodes == 3 and ds.total_steps == 15
    episodes = list(ds.iterate_episodes())
    assert episodes[1].terminations[-1] and not episodes[1].truncations[-1]
    assert episodes[0].truncations[-1] and not episodes[0].terminations[-1]
    assert episodes[0].observations.shape == (6, 4)
    assert (minari_dir / "loco_il_test" / "hopper-run-v0").is_dir()

    back = from_minari("loco_il_test/hopper-run-v0")
    assert_same(back, data)
    assert from_minari(ds, info={"task_id": "X"}).info["task_id"] == "X"


def test_minari_existing_id_and_overwrite(minari_dir):
    to_minari(make_rollouts(seed=1), "loco_il_test/a-v0")
    with pytest.raises(DatasetError, match="already exists"):
        to_minari(make_rollouts(seed=2), "loco_il_test/a-v0")
    new = make_rollouts(seed=2, lengths=(4, 4))
    to_minari(new, "loco_il_test/a-v0", overwrite=True)
    assert_same(from_minari("loco_il_test/a-v0"), new)


def test_minari_rejects_states_only(minari_dir):
    with pytest.raises(DatasetError, match="require actions"):
        to_minari(make_rollouts(actions=False), "loco_il_test/real-v0")


def test_minari_rejects_inconsistent_next_obs(minari_dir):
    data = make_rollouts()
    next_obs = data.next_obs.copy()
    next_obs[2] += 1.0
    with pytest.raises(DatasetError, match=r"next_obs\[t\] == obs\[t\+1\]"):
        to_minari(data.replace(next_obs=next_obs), "loco_il_test/bad-v0")


def test_from_foreign_minari_dataset(minari_dir):
    import gymnasium as gym
    import minari
    from minari.data_collector import EpisodeBuffer

    obs = np.arange(12, dtype=np.float32).reshape(4, 3)
    buf = EpisodeBuffer(
        id=0,
        observations=obs,
        actions=np.ones((3, 1), dtype=np.float32),
        rewards=np.array([1.0, 2.0, 3.0]),
        terminations=np.zeros(3, dtype=bool),
        truncations=np.zeros(3, dtype=bool),  # recording stopped without a flag
    )
    with pytest.warns(UserWarning):
        minari.create_dataset_from_buffers(
            "foreign/ds-v0", [buf],
            observation_space=gym.spaces.Box(-np.inf, np.inf, (3,), np.float32),
            action_space=gym.spaces.Box(-1, 1, (1,), np.float32),
        )
    t = from_minari("foreign/ds-v0")
    np.testing.assert_array_equal(t.obs, obs[:-1])
    np.testing.assert_array_equal(t.next_obs, obs[1:])
    np.testing.assert_array_equal(t.last, [False, False, True])
    assert not t.absorbing.any()
    assert t.info["source"] == "minari:foreign/ds-v0" and t.info["dataset_type"] is None
    with pytest.raises(DatasetError, match="no local Minari dataset"):
        from_minari("foreign/missing-v0")


# ----------------------------------------------------------------------------- LocoMuJoCo


JOINTS = ["pelvis_tx", "pelvis_tz", "pelvis_ty", "hip", "knee"]


def _signal(j, t):
    return np.sin(2 * np.pi * (0.5 + 0.3 * j) * t) + 0.1 * j


def write_per_joint(path, n_samples=(1001, 501), freq=500.0, split=True):
    total = sum(n_samples)
    if split:  # time restarts in every episode
        t = np.concatenate([np.arange(n) / freq for n in n_samples])
    else:
        t = np.arange(total) / freq
    arrays = {}
    for j, name in enumerate(JOINTS):
        arrays[f"q_{name}"] = _signal(j, t)
        arrays[f"dq_{name}"] = 10.0 + _signal(j, t)
    arrays["goal_speed"] = np.ones(total)
    if split:
        arrays["split_points"] = np.cumsum([0, *n_samples])
    np.savez(path, **arrays)
    return arrays


def test_locomujoco_per_joint_default_mapping(tmp_path):
    write_per_joint(tmp_path / "walk.npz")
    d = load_locomujoco_npz(tmp_path / "walk.npz")
    names = d.info["obs_names"]
    assert names == ["q_pelvis_ty", "q_hip", "q_knee"] + [f"dq_{j}" for j in JOINTS]
    assert d.info["dataset_type"] == "real" and d.actions is None
    assert d.info["source"] == "locomujoco:walk.npz" and d.info["rewards_available"] is False
    # 1001 samples @500 Hz = 2 s -> 201 samples @100 Hz -> 200 transitions; 501 -> 101 -> 100
    assert d.episode_bounds() == [(0, 200), (200, 300)]
    np.testing.assert_array_equal(d.next_obs[:199], d.obs[1:200])
    t_new = np.arange(201) / 100.0
    for col, name in enumerate(names):
        j = JOINTS.index(name.split("_", 1)[1])
        expected = _signal(j, t_new) + (10.0 if name.startswith("dq_") else 0.0)
        np.testing.assert_allclose(d.obs[:200, col], expected[:-1], atol=1e-5)
        np.testing.assert_allclose(d.next_obs[199, col], expected[-1], atol=1e-5)


def test_locomujoco_per_joint_explicit_order_and_linear(tmp_path):
    write_per_joint(tmp_path / "walk.npz", split=False)
    names = ["dq_knee", "q_knee", "q_pelvis_tx"]
    d = load_locomujoco_npz(tmp_path / "walk.npz", obs_names=names, interpolation="linear",
                            info={"task_id": "HumanoidTorque.walk.real"})
    assert d.info["obs_names"] == names and d.info["task_id"] == "HumanoidTorque.walk.real"
    assert d.n_trajectories == 1 and d.n_transitions == 300  # 1502 samples = 3.002 s -> 301 samples
    t_new = np.arange(301) / 100.0
    np.testing.assert_allclose(d.obs[:, 2], _signal(0, t_new[:-1]), atol=1e-4)  # q_pelvis_tx taken when asked
    np.testing.assert_allclose(d.obs[:, 0], 10.0 + _signal(4, t_new[:-1]), atol=1e-4)

    by_joint = load_locomujoco_npz(tmp_path / "walk.npz", joint_order=["knee", "pelvis_tx", "hip"])
    assert by_joint.info["obs_names"] == ["q_knee", "q_hip", "dq_knee", "dq_pelvis_tx", "dq_hip"]

    same_freq = load_locomujoco_npz(tmp_path / "walk.npz", obs_names=["q_hip"], source_freq=100, target_freq=100)
    assert same_freq.n_transitions == 1501


def test_locomujoco_resampling_between_grids(tmp_path):
    # 120 Hz -> 100 Hz: the target samples fall between source samples
    write_per_joint(tmp_path / "mocap.npz", n_samples=(241,), freq=120.0)
    t_new = np.arange(201) / 100.0  # 240 / 120 Hz = 2 s -> 201 samples
    cubic = load_locomujoco_npz(tmp_path / "mocap.npz", obs_names=["q_knee"], source_freq=120)
    linear = load_locomujoco_npz(tmp_path / "mocap.npz", obs_names=["q_knee"], source_freq=120,
                                 interpolation="linear")
    assert cubic.n_transitions == linear.n_transitions == 200
    err_cubic = np.abs(cubic.obs[:, 0] - _signal(4, t_new[:-1])).max()
    err_linear = np.abs(linear.obs[:, 0] - _signal(4, t_new[:-1])).max()
    assert err_cubic < 1e-4 < err_linear < 3e-3


def test_locomujoco_missing_keys(tmp_path):
    write_per_joint(tmp_path / "walk.npz")
    with pytest.raises(DatasetError) as err:
        load_locomujoco_npz(tmp_path / "walk.npz", obs_names=["q_hip", "q_ankle", "dq_ankle"])
    msg = str(err.value)
    assert "q_ankle" in msg and "dq_ankle" in msg and "walk.npz" in msg
    with pytest.raises(DatasetError, match="does not exist"):
        load_locomujoco_npz(tmp_path / "nope.npz")
    np.savez(tmp_path / "uneven.npz", q_a=np.zeros(10), dq_a=np.zeros(11))
    with pytest.raises(DatasetError, match="different lengths"):
        load_locomujoco_npz(tmp_path / "uneven.npz")


def test_locomujoco_states_layout(tmp_path):
    rng = np.random.default_rng(0)
    states = rng.standard_normal((10, 3))
    actions = rng.standard_normal((10, 2))
    last = np.zeros(10)
    last[[3, 9]] = 1.0  # two episodes of 4 and 6 states, flags stored as floats
    np.savez(tmp_path / "perfect.npz", states=states, actions=actions, last=last)
    d = load_locomujoco_npz(tmp_path / "perfect.npz", obs_names=["a", "b", "c"])
    assert d.info["dataset_type"] == "perfect" and d.info["obs_names"] == ["a", "b", "c"]
    # final state of each episode has no successor and is dropped
    rows = [0, 1, 2, 4, 5, 6, 7, 8]
    np.testing.assert_array_equal(d.obs, states[rows])
    np.testing.assert_array_equal(d.next_obs, states[[r + 1 for r in rows]])
    np.testing.assert_array_equal(d.actions, actions[rows])
    assert d.episode_bounds() == [(0, 3), (3, 8)]
    assert not d.absorbing.any() and not d.rewards.any()

    absorbing = np.zeros(10)
    absorbing[3] = 1
    rewards = np.arange(10.0)
    np.savez(tmp_path / "full.npz", states=states, actions=actions, last=last, absorbing=absorbing,
             next_states=states + 1, rewards=rewards)
    f = load_locomujoco_npz(tmp_path / "full.npz", dtype=np.float32)
    assert f.n_transitions == 10 and f.obs.dtype == np.float32
    np.testing.assert_array_equal(f.absorbing, absorbing.astype(bool))
    np.testing.assert_array_equal(f.rewards, rewards)
    assert f.info["rewards_available"] is True

    np.savez(tmp_path / "noact.npz", states=states, last=last)
    with pytest.raises(DatasetError, match="actions"):
        load_locomujoco_npz(tmp_path / "noact.npz")


def test_locomujoco_result_survives_save_load(tmp_path):
    write_per_joint(tmp_path / "walk.npz")
    d = load_locomujoco_npz(tmp_path / "walk.npz")
    assert_same(Trajectories.load(d.save(tmp_path / "converted.npz")), d)


def test_minari_recovers_the_loco_il_env(minari_dir, tmp_path, monkeypatch):
    import minari
    from loco_il import LocoEnv
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path / "datasets"))
    env = LocoEnv.make("InvertedPendulum.balance.perfect")
    data = env.create_dataset(n_episodes=2, verbose=False)
    to_minari(data, "loco_il_test/pendulum-v0")
    recovered = minari.load_dataset("loco_il_test/pendulum-v0").recover_environment()
    obs, _ = recovered.reset(seed=0)
    assert recovered.unwrapped.loco_env.task_id == "InvertedPendulum.balance.perfect"
    assert obs.shape == (data.obs_dim,)
    recovered.close()
