"""The `real` datasets of the humanoids: retargeted motion capture as observations, cached; clear errors for
missing motion files and tasks without motion."""
from __future__ import annotations

import numpy as np
import pytest

from loco_il import LocoEnv
from loco_il.datasets import DatasetError, Trajectories
from loco_il.datasets.providers import ProviderUnavailableError
from loco_il.datasets.real import real_provider, result_to_trajectories
from loco_il.motion.mocap.clips import MotionFilesMissingError
from loco_il.motion.mocap.retarget import retarget_clip
from retarget_common import KEYPOINT_BOUND, PENETRATION_BOUND, cached_env, synthetic_walk


def test_dataset_from_retargeted_clip_validates_and_round_trips(tmp_path):
    env = cached_env("Humanoid.run.perfect")
    res = retarget_clip(env, synthetic_walk())
    data = result_to_trajectories(env, [res, res], info={"source": "synthetic"})
    assert data.actions is None and data.obs.shape[1] == env.obs_spec.dim
    assert data.info["dataset_type"] == "real" and data.info["obs_names"] == list(env.obs_spec.names)
    assert data.n_trajectories == 2 and not data.absorbing.any()
    np.testing.assert_array_equal(data.obs[1:res.n_frames - 1], data.next_obs[:res.n_frames - 2])
    path = data.save(tmp_path / "real.npz")
    back = Trajectories.load(path)
    np.testing.assert_array_equal(back.obs, data.obs)
    np.testing.assert_array_equal(back.next_obs, data.next_obs)
    assert back.info == data.info
    # the observation is the env's: replaying a state gives the stored observation
    np.testing.assert_allclose(env.set_sim_state(res.qpos[3], res.qvel[3]), data.obs[3])


def test_missing_motion_files_error(tmp_path, monkeypatch):
    env = cached_env("UnitreeH1.walk.real")
    user = tmp_path / "my_clips"
    user.mkdir()
    monkeypatch.setenv("LOCO_IL_MOCAP", str(user))
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path / "datasets"))
    with pytest.raises(MotionFilesMissingError) as info:
        env.create_dataset(clips=["cmu_bvh/01_01.bvh"], verbose=False)
    msg = str(info.value)
    assert "01_01.bvh" in msg and str(user) in msg and "LOCO_IL_MOCAP" in msg
    assert isinstance(info.value, DatasetError)


def test_tasks_and_bodies_without_motion_are_explained(tmp_path, monkeypatch):
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path))
    with pytest.raises(ProviderUnavailableError, match="no motion capture is mapped to the task 'stand'"):
        cached_env("UnitreeH1.stand.real").create_dataset(verbose=False)
    # quadrupeds' real data come from the gait generator (the dispatcher); the mocap provider itself refuses them
    with pytest.raises(ProviderUnavailableError, match="keypoint map"):
        real_provider(cached_env("UnitreeA1.simple.real"), verbose=False)


def test_real_provider_builds_and_caches(tmp_path, monkeypatch):
    monkeypatch.delenv("LOCO_IL_MOCAP", raising=False)
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path))
    env = LocoEnv.make("UnitreeH1.walk.real")
    data = env.create_dataset(n_episodes=1, verbose=False)
    assert data.actions is None and data.obs.shape[1] == env.obs_spec.dim
    info = data.info
    assert info["dataset_type"] == "real" and info["task_id"] == "UnitreeH1.walk.real" and info["seed"] is None
    assert "MIT" in info["source"] and info["sources"][0]["file"] == "humanoid3d_walk.txt"
    q = info["quality"]
    assert q["keypoint_error_m"] < KEYPOINT_BOUND and q["penetration_max_m"] <= PENETRATION_BOUND
    assert q["in_limits_fraction"] == 1.0 and q["frames"] >= 1000      # repeated to 10 s at 100 Hz
    files = sorted(tmp_path.rglob("real-*.npz"))
    assert len(files) == 2                                             # the dataset and its initial states
    stamp = [f.stat().st_mtime_ns for f in files]
    again = env.create_dataset(n_episodes=1, verbose=False)            # from the cache
    np.testing.assert_array_equal(again.obs, data.obs)
    assert [f.stat().st_mtime_ns for f in files] == stamp
    split = env.create_dataset(n_episodes=1, verbose=False, return_init_states=True)
    init = split[1]
    np.testing.assert_allclose(env.set_sim_state(init.qpos[0], init.qvel[0]), data.obs[0])
