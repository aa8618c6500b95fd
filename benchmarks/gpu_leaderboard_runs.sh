#!/usr/bin/env bash
# Leaderboard runs on one GPU machine within a time limit (docs/leaderboard.md, "On a GPU machine"; results in
# benchmarks/RESULTS.md, "Leaderboard"): the SAC-based runs in SAC_RUNS train side by side with CUDA-graphed
# updates under CUDA's multi-process service (benchmarks/mps.sh), the runs in CPU_RUNS (on-policy, BC) one per
# core beside them. Every run is a protocol run, its command the one `python -m loco_il.benchmark run` makes, with
# only neutral keys added. END_BY seconds after the start, runs still going are stopped with a checkpoint, then
#   $OUT/finished.tgz    eval.json, log.csv, config.yaml of every finished run (the files the leaderboard commits)
#   $OUT/resumable.tgz   the unfinished CPU_RUNS' dirs with their checkpoint (small: no replay memory), to resume
#                        elsewhere with the same command; unfinished SAC runs are listed only (their checkpoint
#                        holds the replay memory)
#   $OUT/summary.txt     each run's state and last logged step
# Unpack both into the protocol's results dir (benchmarks/leaderboard/logs/<protocol>). A run is named
# TASK-ID/ROW/SEED (ROW: the table's algorithm label). Run from the repository root:
#
#     OUT=/tmp/out END_BY=540 SAC_RUNS="Hopper.run.perfect/lsiq/0 Hopper.run.perfect/lsiq/1" \
#         CPU_RUNS="Ant.run.preference/gail/0" bash benchmarks/gpu_leaderboard_runs.sh
#
# Four graphed Hopper runs of 200k env steps took ~480 s side by side on an H100 machine with 16 cores, nine
# on-policy Ant runs of 1M ~500 s beside them. GPU_OVERRIDES="" trains SAC_RUNS on the CPU (a dry run of this
# script without a GPU); EXTRA adds overrides to every run and RESULTS_DIR moves the run dirs (both for tests:
# they change the runs beyond the protocol).
set -u
OUT=${OUT:-/tmp/gpu_leaderboard_runs}
PROTOCOL=${PROTOCOL:-small}
END_BY=${END_BY:-540}
SAC_RUNS=${SAC_RUNS:-}
CPU_RUNS=${CPU_RUNS:-}
GPU_OVERRIDES=${GPU_OVERRIDES-device=cuda algo.params.cuda_graph=true}
EXTRA=${EXTRA:-}
RESULTS_DIR=${RESULTS_DIR:-}
DATA_WORKERS=${DATA_WORKERS:-8}
PY=${PYTHON:-python3}
export PYTHONUNBUFFERED=1 MUJOCO_GL=${MUJOCO_GL:-disable} WANDB_MODE=${WANDB_MODE:-offline}
mkdir -p "$OUT/logs"
stamp() { echo "[gpu_leaderboard_runs $(date +%T) +${SECONDS}s] $*"; }

# the results dir, then one line per run: "<run dir>\t<command>", from the protocol (exact row label, unlike --algos, which also takes
# an algorithm for all its rows)
plan=$($PY - "$PROTOCOL" "$RESULTS_DIR" $SAC_RUNS $CPU_RUNS <<'EOF'
import sys
from pathlib import Path
from loco_il.benchmark.cells import all_cells
from loco_il.benchmark.commands import cell_command
from loco_il.benchmark.protocol import load_protocol
proto = load_protocol(sys.argv[1])
results = Path(sys.argv[2]) if sys.argv[2] else proto.results_dir
cells = {c.key: c for c in all_cells(proto)}
print(results)
for spec in sys.argv[3:]:
    key, _, seed = spec.rpartition("/")
    if key not in cells or not seed.isdigit():
        sys.exit(f"{spec}: not a run of protocol {sys.argv[1]} (TASK-ID/ROW/SEED, e.g. Hopper.run.perfect/lsiq/0)")
    cell = cells[key]
    print(f"{cell.run_dir(results, int(seed))}\t{cell_command(proto, cell, [int(seed)], results_dir=results)}")
EOF
) || exit 2
root=$(head -n 1 <<< "$plan"); plan=$(tail -n +2 <<< "$plan")
n_sac=$(wc -w <<< "$SAC_RUNS")
stamp "start: $n_sac SAC-based runs, $(wc -w <<< "$CPU_RUNS") CPU runs; $(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null)"

# each task's dataset once, before the runs that share it start
for task in $(tr ' ' '\n' <<< "$SAC_RUNS $CPU_RUNS" | cut -d/ -f1 | sort -u); do
    $PY -c "from loco_il import LocoEnv; LocoEnv.make('$task').create_dataset(verbose=False, workers=$DATA_WORKERS)" \
        > "$OUT/logs/dataset_$task.txt" 2>&1 &
done
wait
stamp "datasets ready"
if [[ $n_sac -gt 0 && $GPU_OVERRIDES == *cuda* ]]; then
    source "$(dirname "$0")/mps.sh"   # start_mps, stop_mps
    start_mps > "$OUT/logs/mps.txt" 2>&1 && mps_started=1; stamp "$(tail -n 1 "$OUT/logs/mps.txt")"
fi

pids=(); dirs=(); i=0
while IFS=$'\t' read -r dir cmd; do
    [[ -z $dir ]] && continue
    extra=$EXTRA; [[ $i -lt $n_sac ]] && extra="$GPU_OVERRIDES $EXTRA"
    eval "exec $PY ${cmd#python } $extra" > "$OUT/logs/run$i.txt" 2>&1 &   # exec: $! is train.py itself
    pids+=($!); dirs+=("$dir"); i=$((i + 1))
done <<< "$plan"
stamp "started ${#pids[@]} runs"
while [[ $SECONDS -lt $END_BY ]]; do
    alive=0; for p in "${pids[@]}"; do kill -0 "$p" 2>/dev/null && alive=1; done
    [[ $alive == 0 ]] && break
    sleep 5
done
for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null; done   # train.py checkpoints, then exits
wait
[[ ${mps_started:-0} == 1 ]] && stop_mps

finished=(); resumable=(); : > "$OUT/summary.txt"
for k in "${!dirs[@]}"; do
    d=${dirs[$k]}; last=$(tail -n 1 "$d/log.csv" 2>/dev/null | cut -d, -f1)
    if [[ -f $d/eval.json ]]; then state=finished; finished+=("$d")
    elif [[ $k -ge $n_sac && -f $d/checkpoint.pt ]]; then state="unfinished, resumable"; resumable+=("$d")
    else state=unfinished; fi
    echo "$d: $state (last logged step ${last:-none})" >> "$OUT/summary.txt"
done
rel() { for d in "$@"; do echo "${d#"$root"/}"; done; }
if [[ ${#finished[@]} -gt 0 ]]; then
    (cd "$root" && rel "${finished[@]}" | sed 's|$|/eval.json|; p; s|eval.json$|log.csv|; p; s|log.csv$|config.yaml|' |
        tar czf "$OUT/finished.tgz" -T -)
fi
if [[ ${#resumable[@]} -gt 0 ]]; then
    (cd "$root" && tar czf "$OUT/resumable.tgz" --exclude=checkpoint.prev.pt --exclude=.lock $(rel "${resumable[@]}"))
fi
cat "$OUT/summary.txt"
stamp "end: ${#finished[@]} finished, ${#resumable[@]} resumable"
