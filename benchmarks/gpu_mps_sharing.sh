#!/usr/bin/env bash
# Do several graphed training runs share one GPU better under CUDA's multi-process service (MPS)? (issue #5;
# results in benchmarks/RESULTS.md, "GPU: several runs on one GPU".) Without MPS the GPU
# time-slices between the runs' processes, and four graphed runs made less in sum than two (RESULTS.md,
# "GPU: whole training runs"). This times the same group of runs twice in one call, first without MPS, then with an
# MPS server started here (benchmarks/mps.sh), with benchmarks/train_speed.py, and writes both tables to
# $OUT/mps_sharing.txt.
#
#     OUT=/tmp/out RUNS_SIDE_BY_SIDE=4 SPEED_S=45 ALGO=sqil bash benchmarks/gpu_mps_sharing.sh
#
# With KEEP_MPS=1 a working MPS server is left running on exit (the caller's later CUDA processes then use it when
# they inherit CUDA_MPS_PIPE_DIRECTORY, which this script prints as its last line, `export ...`, to eval); otherwise
# it is stopped. The exit status is 0 when MPS worked, 3 when it could not be started or a client could not use
# it (then nothing is left running), so that a caller can choose how many runs to start.
set -u
OUT=${OUT:-/tmp/gpu_mps_sharing}
N=${RUNS_SIDE_BY_SIDE:-4}
SPEED_S=${SPEED_S:-45}
ALGO=${ALGO:-sqil}
KEEP_MPS=${KEEP_MPS:-0}
PY=${PYTHON:-python3}
export PYTHONUNBUFFERED=1 MUJOCO_GL=${MUJOCO_GL:-disable}
mkdir -p "$OUT"
report=$OUT/mps_sharing.txt
stamp() { echo "[gpu_mps_sharing $(date +%T)] $*" | tee -a "$report" >&2; }
# a small dataset and an early first update (the speed depends on neither); the LayerNorm critic of the SQIL runs
# trained under MPS afterwards
small="dataset.n_episodes=12 algo.params.initial_replay_size=1000 algo.params.cuda_graph=true algo.params.critic_layer_norm=true"
speed() {  # speed LABEL: N graphed runs side by side, SPEED_S seconds
    stamp "$1: $N graphed $ALGO runs side by side, ${SPEED_S} s"
    $PY benchmarks/train_speed.py --algo "$ALGO" --seconds "$SPEED_S" --every 500 --groups "cuda:$N" -- $small >> "$report" 2>&1
    stamp "$1: exit $?"
}

stamp "start; $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null)"
speed "without MPS"

source "$(dirname "$0")/mps.sh"   # start_mps, stop_mps
start_mps >> "$report" 2>&1; rc=$?
stamp "$(grep '^MPS:' "$report" | tail -n 1)"
if [[ $rc != 0 ]]; then exit 3; fi
speed "with MPS"
if [[ $KEEP_MPS != 1 ]]; then stop_mps; stamp "MPS stopped"; fi
echo "export CUDA_MPS_PIPE_DIRECTORY=$CUDA_MPS_PIPE_DIRECTORY CUDA_MPS_LOG_DIRECTORY=$CUDA_MPS_LOG_DIRECTORY"
