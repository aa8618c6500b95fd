#!/usr/bin/env bash
# Motion-tracking expert runs of the humanoid robots: start or resume them in the background, and keep their
# slim states in git so that a run goes on from another machine.
#
#   bash benchmarks/tracking_runs.sh resume Atlas.walk UnitreeH1.walk   # copy the committed state into runs/ if
#                                                                      # runs/ has none, then train in background
#   bash benchmarks/tracking_runs.sh save Atlas.walk UnitreeH1.walk     # copy runs/ -> benchmarks/expert_runs/
#   bash benchmarks/tracking_runs.sh status                             # last progress line of every run
#   FROM=4400000 bash benchmarks/tracking_runs.sh evaluate Atlas.walk   # 100-episode evaluation of the kept policies
#   EXTRA="tracking.rsi_fraction=0.3" bash benchmarks/tracking_runs.sh resume Atlas.walk   # more overrides
#   VARIANT=clock1 EXTRA="tracking.clock_ramp_time=1.0 init_from=runs/tracking/UnitreeH1.walk/seed0/checkpoint.pt" \
#     bash benchmarks/tracking_runs.sh resume UnitreeH1.walk          # a variant in runs/tracking/<Task>/seed0-clock1
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

VARIANT=${VARIANT:+-$VARIANT}     # a named variant of a run (its own folders), e.g. VARIANT=clock1
run_dir() { echo "runs/tracking/$1/seed$SEED$VARIANT"; }
saved_dir() { echo "benchmarks/expert_runs/$1_tracking_seed$SEED$VARIANT"; }

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
      # snapshots are the preference levels of an expert to come; once the task's expert ships with its levels
      # (loco_il/experts/shipped/<Task>/snapshots) they are not kept here
      if [ -d "$run/snapshots" ] && [ ! -d "loco_il/experts/shipped/$task/snapshots" ]; then
        mkdir -p "$saved/snapshots" && cp "$run"/snapshots/*.pt "$saved/snapshots"/
      fi
      echo "$task: saved $(du -sh "$saved" | cut -f1) to $saved"
    done ;;
  evaluate)
    # the bar's evaluation (100 episodes: 50 standing starts with reset noise, 50 reference states) of every
    # policy the run kept in evals/ (from env step $FROM on) that has no result yet in eval100/; one core
    for task in "$@"; do
      run=$(run_dir "$task"); mkdir -p "$run/eval100"
      for policy in "$run"/evals/step_*.pt; do
        [ -f "$policy" ] || continue                     # none kept yet
        result="$run/eval100/$(basename "$policy" .pt).json"
        step=$(basename "$policy" .pt); step=$((10#${step#step_}))
        [ -f "$result" ] || [ "$step" -lt "${FROM:-0}" ] && continue
        "$PYTHON" -m loco_il.experts eval path="$policy" episodes=100 | tail -n 1 > "$result.tmp" && mv "$result.tmp" "$result"
        "$PYTHON" -c "import json,sys; r=json.load(open(sys.argv[1])); print(sys.argv[1], r['terminated'], 'falls,', \
          'return', r['return_mean'], 'speed', r['forward_speed_mean'])" "$result"
      done
    done ;;
  status)
    for log in runs/tracking/*/seed*/train.log; do
      [ -f "$log" ] && echo "$log: $(grep '\] step ' "$log" | tail -n 1 | cut -c1-160)"
    done ;;
  *) echo "usage: bash benchmarks/tracking_runs.sh resume|save|evaluate|status [Task ...]" >&2; exit 2 ;;
esac
