"""Items 3 and 4: every config value is typed and range-checked before anything is built; a bad one is one line
on stderr, exit status 2, and no run dir."""
from __future__ import annotations

import subprocess

import pytest
from train_helpers import ROOT, TASK, train

from loco_il.experiment.config_schema import ConfigValueError, validate_config
from loco_il.experiment.hydra_callbacks import task_config


def composed(*overrides: str):
    """train.py's config for `overrides`, as its task function receives it."""
    from hydra import compose, initialize_config_dir
    from hydra.core.hydra_config import HydraConfig
    with initialize_config_dir(config_dir=str(ROOT / "experiment_configs"), version_base="1.3"):
        cfg = compose("config", overrides=list(overrides), return_hydra_config=True)
    HydraConfig.instance().set_config(cfg)
    return task_config(cfg)


def test_the_default_config_is_valid(tmp_path):
    cfg = validate_config(composed(f"results_dir={tmp_path}"))
    assert cfg["task_id"] == TASK and cfg["seed"] == 0 and cfg["dataset"]["regenerate"] is False


@pytest.mark.parametrize("override, message", [
    ("n_steps=-5", "n_steps=-5: expected an integer >= 1"),
    ("n_steps=0", "n_steps=0: expected an integer >= 1"),
    ("n_steps=1.5", "n_steps=1.5: expected an integer"),
    ("n_steps=abc", "n_steps='abc': expected an integer"),
    ("seed=1.5", "seed=1.5: expected an integer"),
    ("seed=abc", "seed='abc': expected an integer"),
    ("seed=-1", "seed=-1: expected an integer >= 0"),
    ("eval.every=-10", "eval.every=-10: expected an integer >= 1"),
    ("eval.episodes=0", "eval.episodes=0: expected an integer >= 1"),
    ("eval.final_episodes=0", "eval.final_episodes=0: expected an integer >= 1"),
    ("resume=maybe", "resume=maybe: expected auto, true"),
    ("device=gpu", "device=gpu: not a torch device; use device=cpu"),
    ("dataset.workers=0", "dataset.workers=0: expected an integer >= 1"),
    ("dataset.portion=[0.5,0.2]", "dataset.portion=[0.5, 0.2]: expected [start, end]"),
    ("checkpoint_every=0", "checkpoint_every=0: expected an integer >= 1"),
    ("init_state=middle", "init_state='middle': expected one of default, dataset"),
    ("+n_step=100", "unknown config key 'n_step'"),
])
def test_invalid_values_are_named(tmp_path, override, message):
    with pytest.raises(ConfigValueError) as err:
        validate_config(composed(f"results_dir={tmp_path}", override))
    assert message in str(err.value) and "\n" not in str(err.value)


def test_cuda_on_a_machine_without_cuda():
    import torch
    cfg = composed("device=cuda")
    if torch.cuda.is_available():
        validate_config(cfg, check_paths=False)
        with pytest.raises(ConfigValueError, match="CUDA device"):
            validate_config(composed(f"device=cuda:{torch.cuda.device_count()}"), check_paths=False)
    else:
        with pytest.raises(ConfigValueError, match="no CUDA device .* use device=cpu"):
            validate_config(cfg, check_paths=False)


def test_results_dir_that_is_a_file(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(ConfigValueError, match="is a file, not a folder"):
        validate_config(composed(f"results_dir={tmp_path / 'file'}"))
    with pytest.raises(ConfigValueError, match="is a file, not a folder"):
        validate_config(composed(f"results_dir={tmp_path / 'file' / 'below'}"))


def _one_line_exit_2(proc: subprocess.CompletedProcess, message: str) -> None:
    assert proc.returncode == 2, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], proc.stderr[-2000:]


@pytest.mark.parametrize("override, message", [
    ("n_steps=-5", "n_steps=-5: expected an integer >= 1"),
    ("seed=abc", "seed='abc': expected an integer"),
    ("device=gpu", "device=gpu: not a torch device"),
])
@pytest.mark.slow
def test_train_py_refuses_before_making_the_run_dir(env_vars, tmp_path, override, message):
    proc = train(env_vars, tmp_path / "r", "algo=bc", override, check=False, timeout=120)
    _one_line_exit_2(proc, message)
    assert not (tmp_path / "r" / TASK).exists()


@pytest.mark.slow
def test_train_py_with_a_read_only_results_dir(env_vars, tmp_path, make_read_only):
    from conftest import read_only
    from train_helpers import train_command
    folder = make_read_only(tmp_path / "ro")
    proc = subprocess.run(read_only(train_command(folder, "algo=bc"), [folder]), cwd=ROOT, env=env_vars,
                          capture_output=True, text=True, timeout=120)
    _one_line_exit_2(proc, f"results_dir={folder}: cannot write there")
