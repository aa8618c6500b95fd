"""Experiments: the training loop behind `train.py` (runner), run logs (logging), checkpoints (checkpoint).

    from loco_il.experiment import run
    result = run(cfg, run_dir)       # cfg: the composed experiment_configs/config.yaml (DictConfig or dict)
"""
from loco_il.experiment.runner import STOPPED_EXIT_CODE, ExperimentConfigError, StopRequested, run

__all__ = ["run", "StopRequested", "STOPPED_EXIT_CODE", "ExperimentConfigError"]
