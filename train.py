"""Training entry point (`python train.py task=... algo=...`): not wired yet.

The Hydra experiment runner is issue #6. Until it lands this script says so and exits with an
error instead of pretending to train; use `python -m loco_il.rollout` to exercise the environments.
"""
import sys

if __name__ == "__main__":
    sys.exit("train.py is not implemented yet (issue #6: Hydra experiments). "
             "Run `python -m loco_il.rollout --task Hopper.run.perfect` to try an environment.")
