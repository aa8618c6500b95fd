"""Train an imitation-learning agent: `python train.py task=<Task-ID> algo=<name> [key=value ...]`.

A Hydra app (configs in experiment_configs/: config.yaml + groups algo/, logger/, eval/, task/).
`python train.py --help` lists the options, `python train.py --cfg job` prints the composed config,
`python train.py -m algo=bc,sqil seed=0,1` sweeps (`hydra/launcher=joblib` runs the jobs in parallel,
`hydra/launcher=submitit_local` / `submitit_slurm` as submitit jobs). The training loop lives in
loco_il/experiment/runner.py; re-running a command continues its killed run from the last checkpoint.
The config is validated before anything runs (loco_il/experiment/config_schema.py); a sweep ends with one line
per job and exits 1 when a job failed (loco_il/experiment/hydra_callbacks.py).
"""
import os
import sys
from pathlib import Path

os.environ.setdefault("WANDB_SILENT", "true")
os.environ.setdefault("MUJOCO_GL", "egl")

import hydra  # noqa: E402
from omegaconf import DictConfig  # noqa: E402

CONFIG_DIR = str(Path(__file__).resolve().parent / "experiment_configs")


@hydra.main(config_path=CONFIG_DIR, config_name="config", version_base="1.3")
def main(cfg: DictConfig):
    from hydra.core.hydra_config import HydraConfig

    from loco_il.experiment.runner import run_job
    hc = HydraConfig.get()
    single = hc.mode.name == "RUN"
    outcome = run_job(cfg, hc.runtime.output_dir, list(hc.overrides.task), catch_all=not single)
    if single:
        sys.exit(outcome.code)   # single runs: the exit status says what happened
    return outcome               # sweeps go on with the next job; the summary at the end names every outcome


if __name__ == "__main__":
    main()
