#!/usr/bin/env bash
# Motion-tracking expert runs of the humanoid robots: start or resume them in the background, and keep their
# slim states in git so that a run goes on from another machine.
#
#   bash benchmarks/tracking_runs.sh resume Atlas.walk UnitreeH1.walk   # copy the committed state into runs/ if
#                                                                      # runs/ has none, then train in background
#   bash benchmarks/tracking_runs.sh save Atlas.walk UnitreeH1.walk     # copy runs/ -> benchmarks/expert_runs/
#   bash benchmarks/tracking_runs.sh status                             # last progress line of every run
#   EXTRA="tracking.rsi_fraction=0.3" bash benchmarks/tracking_runs.sh resume Atlas.walk   # more overrides
#
# A run is `python -m loco_il.experts train task=<Task> algo=tracking` into runs/tracking/<Task>/seed$SEED with
# 8 envs in one process (one core per run: on a 2-core machine two runs side by side; with more cores use
# NUM_ENVS=16 ASYNC=true). The committed state is the run's checkpoint (policy, value network, optimizers,
# normalizers, reference; ~2 MB), its evals.jsonl, its log and its snapshots (preference levels later).
set -euo pipefail
cd "$(dirname "$0")/.."

SEED=${SEED:-0}
NUM_ENVS=${NUM_ENVS:-8}
ASYNC=${ASYNC:-false}
TOTAL=${TOTAL:-20000000}
PYTHON=${PYTHON:-python}
verb=${1:-status}
shift || true

run_dir() { echo "runs/tracking/$1/seed$SEED"; }
saved_dir() { echo "benchmarks/expert_runs/$1_tracking_seed$SEED"; }

case "$verb" in
  resume)
    for task in "$@"; do
      run=$(run_dir "$task"); saved=$(saved_dir "$task")
      if [ ! -f "$run/checkpoint.pt" ] && [ -f "$saved/checkpoint.pt" ]; then
        mkdir -p "$run" && cp -r "$saved"/checkpoint.pt "$saved"/evals.jsonl "$run"/
        [ -d "$saved/snapshots" ] && cp -r "$saved/snapshots" "$run"/
      fi
      mkdir -p "$run"
      nohup "$PYTHON" -m loco_il.experts train task="$task" algo=tracking seed="$SEED" total_steps="$TOTAL" \
        num_envs="$NUM_ENVS" async="$ASYNC" out_dir="$run" checkpoint_minutes=4 log_interval_s=60 ${EXTRA:-} \
        >> "$run/train.log" 2>&1 &
      echo "$task: training in the background (pid $!), log $run/train.log"
    done ;;
  save)
    for task in "$@"; do
      run=$(run_dir "$task"); saved=$(saved_dir "$task")
      [ -f "$run/checkpoint.pt" ] || { echo "$task: no checkpoint in $run" >&2; exit 2; }
      mkdir -p "$saved"
      cp "$run/checkpoint.pt" "$run/evals.jsonl" "$saved"/
      [ -f "$run/train.log" ] && cp "$run/train.log" "$saved"/
      [ -d "$run/snapshots" ] && mkdir -p "$saved/snapshots" && cp "$run"/snapshots/*.pt "$saved/snapshots"/
      echo "$task: saved $(du -sh "$saved" | cut -f1) to $saved"
    done ;;
  status)
    for log in runs/tracking/*/seed*/train.log; do
      [ -f "$log" ] && echo "$log: $(grep '\] step ' "$log" | tail -n 1 | cut -c1-160)"
    done ;;
  *) echo "usage: bash benchmarks/tracking_runs.sh resume|save|status [Task ...]" >&2; exit 2 ;;
esac
