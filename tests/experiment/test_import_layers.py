"""`loco_il.evaluation` and `loco_il.experiment` import alone in a fresh interpreter, and the training loop's package
does not pull in the evaluation package when it is imported (evaluation sits above experiment: it reads run dirs)."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest
from train_helpers import ROOT  # tests/ is on sys.path


def _python(code: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=300)


@pytest.mark.parametrize("module", ["loco_il.evaluation", "loco_il.experiment", "loco_il.evaluation.runs",
                                    "loco_il.evaluation.progress", "loco_il.experiment.runner",
                                    "loco_il.datasets.loading"])
def test_imports_alone(module):
    proc = _python(f"import {module}")
    assert proc.returncode == 0, proc.stderr[-3000:]


def test_the_experiment_package_does_not_import_evaluation_at_module_level():
    proc = _python("import sys, loco_il.experiment.runner; "
                   "print(sorted(m for m in sys.modules if m.startswith('loco_il.evaluation')))")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip() == "[]"
