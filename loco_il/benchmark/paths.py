"""Where the benchmark's files live: protocols, train.py, run dirs and tables, all relative to the source checkout.

Commands are run from the checkout's root, so the paths they name (`results_dir=benchmarks/leaderboard/logs/...`)
are relative and the printed commands work on any clone.
"""
from __future__ import annotations

from pathlib import Path

import loco_il

#: the source checkout holding train.py, experiment_configs/ and benchmarks/
ROOT = Path(loco_il.__file__).resolve().parents[1]
PROTOCOL_DIR = ROOT / "experiment_configs" / "benchmark"
TRAIN_SCRIPT = ROOT / "train.py"
#: leaderboard tables (<protocol>.md, .csv) and their figures (curves/<protocol>/)
TABLE_DIR = ROOT / "benchmarks" / "leaderboard"
#: run dirs of every protocol: <LOGS_DIR>/<protocol>/<Task-ID>/<label>/seed<k>/
LOGS_DIR = TABLE_DIR / "logs"


def relative(path: Path) -> str:
    """`path` relative to the checkout's root when it lies inside it (commands run from there), else absolute."""
    try:
        return str(Path(path).resolve().relative_to(ROOT))
    except ValueError:
        return str(Path(path).resolve())


def check_train_script() -> Path:
    """train.py of the checkout; a one-line error when loco_il was installed without its sources."""
    if not TRAIN_SCRIPT.is_file():
        raise FileNotFoundError(f"{TRAIN_SCRIPT} not found: the benchmark runs train.py of a source checkout; "
                                f"install loco_il from one with `pip install -e .`")
    return TRAIN_SCRIPT
