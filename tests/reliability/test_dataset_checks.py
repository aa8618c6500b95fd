"""Item 6: a dataset that does not fit the env is refused (another task, scaled actions) or warned about
(another MuJoCo version, missing metadata); a file that is no dataset is told apart from a damaged one."""
from __future__ import annotations

import numpy as np
import pytest
from train_helpers import TASK, make_env_vars

from loco_il.datasets import create_dataset
from loco_il.datasets.trajectory import DatasetError, Trajectories


@pytest.fixture(scope="module")
def cached(tmp_path_factory):
    """The stand-in expert's 4-episode dataset of InvertedPendulum, generated into a private cache: (env, file)."""
    from loco_il.environments.registry import make
    root = tmp_path_factory.mktemp("checks")
    env_vars = make_env_vars(root)
    patch = pytest.MonkeyPatch()
    for key in ("LOCO_IL_EXPERTS", "LOCO_IL_DATASETS"):
        patch.setenv(key, env_vars[key])
    env = make(TASK)
    create_dataset(env, n_episodes=4, verbose=False)
    (path,) = [p for p in (root / "datasets").rglob("*.npz")
               if not p.name.endswith(".init_states.npz")]
    yield env, path, path.read_bytes()
    env.stop()
    patch.undo()


def _edit(cached, **changes) -> None:
    """Rewrite the cached file with `changes` (info keys, or actions=<array>); the rest kept."""
    env, path, original = cached
    path.write_bytes(original)
    data = Trajectories.load(path)
    info = dict(data.info)
    actions = changes.pop("actions", data.actions)
    info.update(changes)
    Trajectories(data.obs, data.next_obs, actions, data.rewards, data.absorbing, data.last, info).save(path)


def test_scaled_actions_are_refused(cached):
    env, _, _ = cached
    actions = Trajectories.load(cached[1]).actions
    _edit(cached, actions=actions / np.abs(actions).max() * 50)   # full-range actions x50
    with pytest.raises(DatasetError, match=r"actions lie in .* takes actions in \[-1, 1\].*dataset.regenerate=true"):
        create_dataset(env, n_episodes=4, verbose=False)


def test_a_dataset_of_another_task_is_refused(cached):
    env, _, _ = cached
    _edit(cached, task_id="Hopper.run.perfect")
    with pytest.raises(DatasetError, match=f"recorded for Hopper.run.perfect, not for {TASK}"):
        create_dataset(env, n_episodes=4, verbose=False)


def test_another_mujoco_version_is_warned_about(cached, capsys):
    env, _, _ = cached
    _edit(cached, simulator="mujoco 2.3.0")
    data = create_dataset(env, n_episodes=4, verbose=False)
    assert data.n_trajectories == 4
    err = capsys.readouterr().err
    assert "warning: the dataset was recorded with mujoco 2.3.0, this is mujoco" in err


def test_missing_metadata_is_warned_about(cached, capsys):
    from loco_il.datasets.env_check import check_dataset_for_env
    env, path, original = cached
    path.write_bytes(original)
    data = Trajectories.load(path)
    bare = Trajectories(data.obs, data.next_obs, data.actions, data.rewards, data.absorbing, data.last, {})
    (warning,) = check_dataset_for_env(bare, env)
    assert "lacks task_id, obs_names, simulator" in warning


def test_the_unchanged_cache_loads_without_warnings(cached, capsys):
    env, path, original = cached
    path.write_bytes(original)
    assert create_dataset(env, n_episodes=4, verbose=False).n_trajectories == 4
    assert "warning" not in capsys.readouterr().err


@pytest.mark.parametrize("name, content, kind", [
    ("log.csv", b"step,return\n1,2\n", "a text file"),
    ("x.npy", None, "a single .npy array"),
])
def test_a_file_that_is_no_dataset(tmp_path, name, content, kind):
    path = tmp_path / name
    if content is None:
        np.save(path, np.zeros(3))
    else:
        path.write_bytes(content)
    with pytest.raises(DatasetError) as err:
        Trajectories.load(path)
    msg = str(err.value)
    assert f"is not a dataset file: it is {kind}" in msg and "delete" not in msg and "\n" not in msg


def test_a_damaged_dataset_is_told_apart(tmp_path, cached):
    path = tmp_path / "d.npz"
    path.write_bytes(cached[2][: len(cached[2]) // 2])
    with pytest.raises(DatasetError, match="truncated or corrupt"):
        Trajectories.load(path)
