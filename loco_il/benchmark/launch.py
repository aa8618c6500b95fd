"""Running the missing runs of a protocol: one `train.py -m` (Hydra multirun) per planned sweep, one after the
other, from the checkout's root. Launcher overrides (`hydra/launcher=joblib hydra.launcher.n_jobs=2`, submitit,
SLURM) are passed through to every sweep, so the runs of a sweep go wherever Hydra's launcher sends them."""
from __future__ import annotations

import subprocess
import sys
from typing import Callable, Mapping, Sequence

from loco_il.benchmark import paths
from loco_il.benchmark.commands import Launch

#: train.py keys that change where or how fast a run trains, not what it computes
NEUTRAL_KEYS = ("device", "torch_threads", "dataset.workers", "logger.progress", "algo.params.cuda_graph")


def changes_results(override: str) -> bool:
    """Whether a passed-through override changes the runs' config beyond the protocol (not a Hydra or launcher
    setting, nor a neutral key such as device)."""
    key = override.lstrip("+~").split("=", 1)[0]
    return not (key.startswith(("hydra/", "hydra.")) or key in NEUTRAL_KEYS)


def execute(launches: Sequence[Launch], extra: Sequence[str] = (), env: Mapping[str, str] | None = None,
            echo: Callable[[str], None] = print) -> int:
    """Run every sweep; 0 when all succeeded, 130 when interrupted (the running train.py jobs checkpoint
    first), else 1. A failed sweep does not stop the ones after it."""
    script = paths.check_train_script()
    failed = 0
    for i, launch in enumerate(launches, 1):
        echo(f"[benchmark] sweep {i}/{len(launches)}, {launch.n_runs} run(s): {launch.display(extra)}")
        code, interrupted = _wait(subprocess.Popen([sys.executable, str(script), *launch.args(extra)],
                                                   cwd=paths.ROOT, env=dict(env) if env is not None else None), echo)
        if interrupted or code == 130:
            echo("[benchmark] stopped; re-run the same command to resume (finished runs are skipped)")
            return 130
        if code != 0:
            failed += 1
            echo(f"[benchmark] sweep {i} exited {code} (its summary above names the failed runs)")
    if failed:
        echo(f"[benchmark] {failed} of {len(launches)} sweep(s) had failed runs")
    return 1 if failed else 0


def _wait(proc: subprocess.Popen, echo: Callable[[str], None]) -> tuple[int, bool]:
    """The sweep's exit status, and whether Ctrl-C was pressed. The sweep gets the same SIGINT and stops its
    running job with a checkpoint, so it is waited for, never killed (killing it would lose the checkpoint)."""
    interrupted = False
    while True:
        try:
            return proc.wait(), interrupted
        except KeyboardInterrupt:
            if not interrupted:
                echo("[benchmark] Ctrl-C: the running job stops with a checkpoint; no further sweep starts "
                     "(a sweep goes on with its next job as `train.py -m` does: Ctrl-C again stops that one)")
            interrupted = True


__all__ = ["execute", "changes_results"]
