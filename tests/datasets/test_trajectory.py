"""Tests of loco_il.datasets.trajectory / splits: format, validation, save/load, splits."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from loco_il.datasets import DatasetError, Trajectories
from loco_il.datasets.npz import DEFAULT_REGENERATE_HINT
from loco_il.datasets.splits import make_split
from loco_il.datasets.trajectory import FORMAT_VERSION, REQUIRED_INFO_KEYS

from dataset_factories import assert_same, make_dataset  # tests/datasets is on sys.path under pytest


# ----------------------------------------------------------------------------- basics


def test_sizes_and_episode_helpers():
    d = make_dataset(lengths=(5, 3, 7))
    assert d.n_transitions == len(d) == 15
    assert d.n_trajectories == 3
    assert d.obs_dim == 4 and d.act_dim == 2
    assert d.episode_bounds() == [(0, 5), (5, 8), (8, 15)]
    np.testing.assert_array_equal(d.episode_lengths(), [5, 3, 7])
    ep = d.trajectory(1)
    assert ep.n_transitions == 3 and ep.n_trajectories == 1
    np.testing.assert_array_equal(ep.obs, d.obs[5:8])
    assert ep.absorbing[-1]  # episode 1 terminated
    np.testing.assert_array_equal(d.trajectory(-1).obs, d.obs[8:])
    with pytest.raises(IndexError):
        d.trajectory(3)
    assert [e.n_transitions for e in d.iter_trajectories()] == [5, 3, 7]


def test_missing_info_keys_are_filled_and_info_is_normalized():
    d = make_dataset()
    d2 = Trajectories(d.obs, d.next_obs, d.actions, d.rewards, d.absorbing, d.last,
                      {"obs_names": tuple(f"o{j}" for j in range(4)), "mean": np.float32(2.5), "seed": np.int64(7)})
    for key in REQUIRED_INFO_KEYS:
        assert key in d2.info
    assert d2.info["task_id"] is None
    assert d2.info["obs_names"] == ["o0", "o1", "o2", "o3"]
    assert type(d2.info["mean"]) is float and d2.info["mean"] == 2.5
    assert type(d2.info["seed"]) is int


def test_episode_returns():
    d = make_dataset(lengths=(5, 3, 7))
    expected = [d.rewards[a:b].sum() for a, b in d.episode_bounds()]
    np.testing.assert_allclose(d.episode_returns(), expected)
    g = 0.9
    disc = [np.sum(d.rewards[a:b] * g ** np.arange(b - a)) for a, b in d.episode_bounds()]
    np.testing.assert_allclose(d.episode_returns(gamma=g), disc)


def test_select_and_concatenate():
    d = make_dataset(lengths=(5, 3, 7, 2))
    sel = d.select_episodes([3, 0])
    assert sel.episode_bounds() == [(0, 2), (2, 7)]
    np.testing.assert_array_equal(sel.obs[:2], d.obs[15:17])
    np.testing.assert_array_equal(sel.obs[2:], d.obs[0:5])
    np.testing.assert_array_equal(sel.actions[2:], d.actions[0:5])
    back = Trajectories.concatenate([d.trajectory(i) for i in range(d.n_trajectories)])
    assert_same(back, d)
    with pytest.raises(DatasetError, match="obs_dim"):
        Trajectories.concatenate([d, make_dataset(obs_dim=5)])
    with pytest.raises(DatasetError, match="actions"):
        Trajectories.concatenate([make_dataset(), make_dataset(actions=False)])


def test_sha256_depends_on_content():
    a, b = make_dataset(seed=1), make_dataset(seed=1)
    assert a.sha256() == b.sha256()
    b.rewards[0] += 1.0
    assert a.sha256() != b.sha256()
    c = make_dataset(seed=1)
    c.info["task_id"] = "other"
    assert a.sha256() != c.sha256()
    assert a.sha256(include_info=False) == c.sha256(include_info=False)


# ----------------------------------------------------------------------------- validation


def _arrays(d):
    return dict(obs=d.obs, next_obs=d.next_obs, actions=d.actions, rewards=d.rewards,
                absorbing=d.absorbing, last=d.last, info=dict(d.info))


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda a: a.update(obs=a["obs"][:, 0]), "2-D"),
        (lambda a: a.update(next_obs=a["next_obs"][:-1]), "next_obs"),
        (lambda a: a.update(actions=a["actions"][:-1]), "actions"),
        (lambda a: a.update(rewards=a["rewards"][:, None]), "rewards"),
        (lambda a: a.update(last=a["last"][:-1]), "last"),
        (lambda a: a.update(absorbing=a["absorbing"].astype(np.int64)), "bool"),
        (lambda a: a.update(obs=a["obs"].astype(np.int64), next_obs=a["next_obs"].astype(np.int64)), "float"),
        (lambda a: a.update(next_obs=a["next_obs"].astype(np.float32)), "dtype"),
        (lambda a: a["obs"].__setitem__((3, 1), np.nan), "non-finite"),
        (lambda a: a["actions"].__setitem__((0, 0), np.inf), "non-finite"),
        (lambda a: a["rewards"].__setitem__(2, np.nan), "non-finite"),
        (lambda a: a["last"].__setitem__(-1, False), "last=True"),
        (lambda a: a["absorbing"].__setitem__(0, True), "absorbing but not last"),
        (lambda a: a["info"].update(obs_names=["a", "b"]), "obs_names"),
        (lambda a: a["info"].update(dataset_type="expert"), "dataset_type"),
        (lambda a: a["info"].update(seed="zero"), "seed"),
        (lambda a: a["info"].update(blob=object()), "JSON"),
        (lambda a: a.update(actions=None), "needs actions"),
        (lambda a: a.update(obs=a["obs"][:0], next_obs=a["next_obs"][:0], actions=a["actions"][:0],
                            rewards=a["rewards"][:0], absorbing=a["absorbing"][:0], last=a["last"][:0]), "N=0"),
    ],
)
def test_validation_rejects(change, message):
    d = make_dataset()
    arrays = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in _arrays(d).items()}
    change(arrays)
    with pytest.raises(DatasetError, match=message):
        Trajectories(**arrays)


def test_dataset_error_is_value_error():
    assert issubclass(DatasetError, ValueError)


def test_validate_catches_later_mutation():
    d = make_dataset()
    d.obs[0, 0] = np.nan
    with pytest.raises(DatasetError, match="non-finite"):
        d.validate()


# ----------------------------------------------------------------------------- save / load


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("actions", [True, False])
def test_round_trip(tmp_path, dtype, actions):
    d = make_dataset(dtype=dtype, actions=actions)
    path = d.save(tmp_path / "data.npz")
    loaded = Trajectories.load(path)
    assert_same(loaded, d)
    assert loaded.sha256() == d.sha256()
    with np.load(path, allow_pickle=False) as z:
        assert int(z["format_version"]) == FORMAT_VERSION
        assert json.loads(str(z["info_json"]))["task_id"] == d.info["task_id"]
        assert "next_obs_last" in z.files and "next_obs" not in z.files  # compact layout
        assert ("actions" in z.files) == actions


def test_round_trip_full_next_obs_layout(tmp_path):
    d = make_dataset()
    next_obs = d.next_obs.copy()
    next_obs[1, 0] += 0.5  # not obs[2] any more: the compact layout cannot be used
    d2 = d.replace(next_obs=next_obs)
    path = d2.save(tmp_path / "data.npz")
    with np.load(path) as z:
        assert "next_obs" in z.files
    assert_same(Trajectories.load(path), d2)


def test_round_trip_keeps_negative_zero(tmp_path):
    d = make_dataset()
    obs, next_obs = d.obs.copy(), d.next_obs.copy()
    obs[1, 0], next_obs[0, 0] = 0.0, -0.0
    d2 = d.replace(obs=obs, next_obs=next_obs)
    loaded = Trajectories.load(d2.save(tmp_path / "d.npz"))
    assert np.signbit(loaded.next_obs[0, 0]) and not np.signbit(loaded.obs[1, 0])
    assert loaded.sha256() == d2.sha256()


def test_save_leaves_no_temp_files_and_overwrites(tmp_path):
    d1, d2 = make_dataset(seed=1), make_dataset(seed=2, lengths=(4, 4))
    d1.save(tmp_path / "d.npz")
    d2.save(tmp_path / "d.npz")
    assert sorted(os.listdir(tmp_path)) == ["d.npz"]
    assert_same(Trajectories.load(tmp_path / "d.npz"), d2)


def test_failed_write_keeps_previous_file(tmp_path, monkeypatch):
    path = tmp_path / "d.npz"
    old = make_dataset(seed=1)
    old.save(path)
    before = path.read_bytes()

    def broken_savez(fh, **arrays):
        fh.write(b"PK partial garbage")
        raise OSError("disk full (simulated)")

    monkeypatch.setattr(np, "savez", broken_savez)
    with pytest.raises(OSError, match="disk full"):
        make_dataset(seed=2).save(path)
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["d.npz"]
    monkeypatch.undo()
    assert_same(Trajectories.load(path), old)


def test_save_creates_parent_dirs(tmp_path):
    path = make_dataset().save(tmp_path / "a" / "b" / "d.npz")
    assert path.is_file()


def _check_load_error(path, match, hint=DEFAULT_REGENERATE_HINT, **kwargs):
    with pytest.raises(DatasetError) as err:
        Trajectories.load(path, **kwargs)
    msg = str(err.value)
    assert str(path) in msg
    assert hint in msg
    assert match in msg
    return msg


def test_load_missing_file(tmp_path):
    _check_load_error(tmp_path / "nope.npz", "does not exist")


def test_load_truncated_file(tmp_path):
    path = make_dataset(lengths=(50, 60)).save(tmp_path / "d.npz")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    _check_load_error(path, "truncated or corrupt")


def test_load_corrupt_bytes(tmp_path):
    path = make_dataset(lengths=(200, 200)).save(tmp_path / "d.npz")
    data = bytearray(path.read_bytes())
    data[len(data) // 3] ^= 0xFF  # inside the array data: caught by the zip CRC
    path.write_bytes(bytes(data))
    _check_load_error(path, "truncated or corrupt")


def test_load_not_a_zip(tmp_path):
    path = tmp_path / "d.npz"
    path.write_bytes(b"this is not a dataset")
    _check_load_error(path, "truncated or corrupt")


def test_load_custom_hint(tmp_path):
    hint = "run `python -m loco_il.datasets.make Hopper.run.perfect`"
    _check_load_error(tmp_path / "nope.npz", "does not exist", hint=hint, regenerate_hint=hint)


def test_load_missing_key(tmp_path):
    path = make_dataset().save(tmp_path / "d.npz")
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files if k != "rewards"}
    np.savez(tmp_path / "bad.npz", **arrays)
    _check_load_error(tmp_path / "bad.npz", "'rewards'")


def test_load_wrong_format_version(tmp_path):
    path = make_dataset().save(tmp_path / "d.npz")
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["format_version"] = np.asarray(FORMAT_VERSION + 1)
    np.savez(tmp_path / "bad.npz", **arrays)
    _check_load_error(tmp_path / "bad.npz", "format version")


@pytest.mark.parametrize("key, bad", [("rewards", "nan"), ("last", "open_end"), ("obs", "shape")])
def test_load_invalid_content(tmp_path, key, bad):
    path = make_dataset().save(tmp_path / "d.npz")
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    if bad == "nan":
        arrays[key][0] = np.nan
        match = "non-finite"
    elif bad == "open_end":
        arrays["last"][-1] = False
        match = "inconsistent"
    else:
        arrays["obs"] = arrays["obs"][:-1]
        match = "inconsistent"
    np.savez(tmp_path / "bad.npz", **arrays)
    _check_load_error(tmp_path / "bad.npz", match)


def test_load_expect(tmp_path):
    d = make_dataset()
    path = d.save(tmp_path / "d.npz")
    ok = Trajectories.load(path, expect={"task_id": d.info["task_id"], "obs_dim": 4, "act_dim": 2,
                                         "obs_names": tuple(d.info["obs_names"])})
    assert_same(ok, d)
    msg = _check_load_error(path, "does not match", expect={"task_id": "Walker.walk.perfect", "obs_dim": 4})
    assert "Walker.walk.perfect" in msg
    _check_load_error(path, "obs_dim", expect={"obs_dim": 17})


# ----------------------------------------------------------------------------- splits


def test_split_default_is_75_25_disjoint_and_complete():
    d = make_dataset(lengths=tuple(range(2, 22)))  # 20 episodes of distinct lengths
    train, test = d.split(split="train"), d.split(split="test")
    tr, te = train.info["split"]["episodes"], test.info["split"]["episodes"]
    assert len(tr) == 15 and len(te) == 5
    assert set(tr).isdisjoint(te) and set(tr) | set(te) == set(range(20))
    assert tr == sorted(tr)
    # the returned data is exactly those episodes
    assert_same(train.replace(info=d.info), d.select_episodes(tr))
    assert train.n_transitions + test.n_transitions == d.n_transitions


def test_split_reproducible_and_seed_dependent():
    d = make_dataset(lengths=(3,) * 30)
    a = d.split(split="train", seed=5)
    b = d.split(split="train", seed=5)
    assert_same(a, b)
    c = d.split(split="train", seed=6)
    assert a.info["split"]["episodes"] != c.info["split"]["episodes"]


def test_split_n_trajectories_and_portion():
    n = 40
    train10 = make_split(n, n_trajectories=10, split="train", seed=3)
    test10 = make_split(n, n_trajectories=10, split="test", seed=3)
    assert len(train10) == 8 and len(test10) == 2  # round(7.5) -> 8 (halves round up)
    pool20 = set(make_split(n, 20, "train", seed=3)) | set(make_split(n, 20, "test", seed=3))
    assert set(train10) | set(test10) <= pool20  # the pool only grows with n_trajectories
    mid = make_split(n, None, "train", portion=(0.25, 0.5), seed=0)
    rest = make_split(n, None, "test", portion=(0.25, 0.5), seed=0)
    assert len(mid) == 10 and len(rest) == 30 and set(mid).isdisjoint(rest)


def test_split_errors():
    d = make_dataset(lengths=(3, 3))
    with pytest.raises(DatasetError, match="empty"):
        d.split(split="test")  # 2 episodes -> 2 train (round(1.5) = 2), 0 test
    with pytest.raises(DatasetError, match="portion"):
        d.split(portion=(0.8, 0.2))
    with pytest.raises(DatasetError, match="n_trajectories"):
        d.split(n_trajectories=3)
    with pytest.raises(DatasetError, match="split must be"):
        d.split(split="validation")
