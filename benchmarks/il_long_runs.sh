#!/usr/bin/env bash
# The imitation-learning runs at the papers' budgets on Hopper.run.perfect, through train.py, so that they
# checkpoint and resume: re-running this script (or one of its lines) continues every run from its last
# checkpoint, so a run can be stopped and resumed any number of times. Results: one row per evaluation in each run dir's log.csv;
# `python -m loco_il.evaluation.progress $RESULTS` shows where every run stands (last evaluation, hours
# left); `python -m loco_il.evaluation.leaderboard $RESULTS` tabulates the finished ones.
#
#   bash benchmarks/il_long_runs.sh              # every run below, one after the other
#   bash benchmarks/il_long_runs.sh lsiq         # some of them
#   RESULTS=/data/il SEEDS="0 1 2" bash benchmarks/il_long_runs.sh lsiq
#
# Budgets: LS-IQ 1.5M env steps (the LS-IQ authors' launchers, github.com/robfiras/ls-iq); IQ-Learn and SQIL 1M
# (IQ-Learn reports its MuJoCo results within 1M steps); GAIL / VAIL / GAIfO 40M (LocoMuJoCo's baselines).
# Cost on the 2-core CPU of this project's development: ~40 env steps/s for the SAC-based ones (one update per
# step: ~10 hours per 1.5M), ~1000 env steps/s for the TRPO-based ones (~11 hours per 40M).
set -euo pipefail
cd "$(dirname "$0")/.."

RESULTS=${RESULTS:-runs/il}
SEEDS=${SEEDS:-0}
TASK=${TASK:-Hopper.run.perfect}
PYTHON=${PYTHON:-python}

declare -A STEPS=([lsiq]=1500000 [iqlearn]=1000000 [sqil]=1000000 [gail]=40000000 [vail]=40000000 [gaifo]=40000000)
declare -A EVAL_EVERY=([lsiq]=50000 [iqlearn]=50000 [sqil]=50000 [gail]=500000 [vail]=500000 [gaifo]=500000)
ORDER=(lsiq iqlearn sqil vail gail gaifo)
ALGOS=("$@")
[ ${#ALGOS[@]} -eq 0 ] && ALGOS=("${ORDER[@]}")

for algo in "${ALGOS[@]}"; do
  [ -n "${STEPS[$algo]:-}" ] || { echo "unknown algorithm '$algo'; one of: ${ORDER[*]}" >&2; exit 2; }
  for seed in $SEEDS; do
    # checkpoints every 25k env steps for the slow off-policy runs (~10 minutes), at every evaluation otherwise
    ckpt=$([ "${EVAL_EVERY[$algo]}" -le 50000 ] && echo 25000 || echo null)
    "$PYTHON" train.py task="$TASK" algo="$algo" seed="$seed" n_steps="${STEPS[$algo]}" \
      eval.every="${EVAL_EVERY[$algo]}" checkpoint_every="$ckpt" results_dir="$RESULTS"
  done
done
