#!/usr/bin/env bash
# Whole CUDA-graphed training runs on a GPU machine (issue #5; results in benchmarks/RESULTS.md,
# "GPU: whole training runs" and "GPU: graphed long runs"). Run from the repository root with torch (CUDA build) and the project's
# dependencies importable; writes its outputs to $OUT (default /tmp/gpu_graphed_runs):
#   cuda_tests.txt          the CUDA tests (pytest -k cuda)
#   train_speed_<algo>.txt  one graphed run alone per algorithm, benchmarks/train_speed.py --seconds $SPEED_S
#   lsiq_runs.tar.gz        log.csv / train.log / config.yaml of graphed LS-IQ runs (seeds $LONG_SEEDS) trained side
#                           by side for $LONG_S seconds, by default with the README's Hopper setting (mixture, twin
#                           critic, LayerNorm), the same seeds and evaluation as the CPU runs in benchmarks/il_results/long_runs
# ONLY_LONG=1 skips the tests and the speed runs. LONG_NAME and LONG_OVERRIDES give the long runs another LS-IQ
# setting (an ablation; LONG_OVERRIDES="" runs LS-IQ's defaults), LONG_ALGO another SAC-based learner (default
# lsiq; its LONG_OVERRIDES must then be that learner's: "" for its defaults), LONG_TASK another task (default
# Hopper.run.perfect); END_BY=<s> stops them that many seconds after the script started, whatever LONG_S says, so
# that one device call can spend all its time training and still return the logs. MPS=1 runs them under CUDA's
# multi-process service (benchmarks/mps.sh; $OUT/mps.txt says whether it started, else they share the GPU
# without it), which made four graphed runs side by side 3.37x faster together.
#
#     OUT=/tmp/out SPEED_S=20 LONG_S=240 LONG_SEEDS="1 2" bash benchmarks/gpu_graphed_runs.sh
#     OUT=/tmp/out ONLY_LONG=1 LONG_S=270 LONG_SEEDS="3 4 5 6" bash benchmarks/gpu_graphed_runs.sh
#     OUT=/tmp/out ONLY_LONG=1 END_BY=540 LONG_SEEDS=2 LONG_NAME=lsiq_mixture_1critic_ln_graph \
#         LONG_OVERRIDES="algo.params.objective=mixture algo.params.n_critics=1 algo.params.critic_layer_norm=true" \
#         bash benchmarks/gpu_graphed_runs.sh
#     OUT=/tmp/out ONLY_LONG=1 MPS=1 END_BY=540 LONG_ALGO=sqil LONG_SEEDS="1 2 3 4" LONG_NAME=sqil_graph \
#         LONG_OVERRIDES="" bash benchmarks/gpu_graphed_runs.sh
set -u
OUT=${OUT:-/tmp/gpu_graphed_runs}
SPEED_S=${SPEED_S:-20}
LONG_S=${LONG_S:-270}
LONG_SEEDS=${LONG_SEEDS:-1 2}
ONLY_LONG=${ONLY_LONG:-0}
LONG_TASK=${LONG_TASK:-Hopper.run.perfect}
LONG_ALGO=${LONG_ALGO:-lsiq}
LONG_NAME=${LONG_NAME:-lsiq_mixture_2critics_ln_graph}
LONG_OVERRIDES=${LONG_OVERRIDES-algo.params.objective=mixture algo.params.n_critics=2 algo.params.critic_layer_norm=true}
END_BY=${END_BY:-}
MPS=${MPS:-0}
RUNS=${RUNS:-/tmp/gpu_graphed_runs_dirs}
PY=${PYTHON:-python3}
export PYTHONUNBUFFERED=1 MUJOCO_GL=${MUJOCO_GL:-disable}
mkdir -p "$OUT" "$RUNS"
stamp() { echo "[gpu_graphed_runs $(date +%T)] $*"; }

stamp "start; $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null)"
# The long runs' dataset (100 expert episodes), generated once here (while the tests run) rather than by each of
# the runs started side by side below, one process per core (in one process 100 Humanoid episodes took ~4.5 min).
$PY -c "import os; from loco_il import LocoEnv; LocoEnv.make('$LONG_TASK').create_dataset(verbose=False, workers=os.cpu_count())" \
    > "$OUT/dataset.txt" 2>&1 &
datagen=$!
if [[ $ONLY_LONG != 1 ]]; then
    $PY -m pytest -q -p no:cacheprovider tests/algorithms/test_offpolicy_losses.py \
        tests/algorithms/test_onpolicy_losses.py tests/experiment/test_train.py -k cuda 2>&1 | tail -n 25 > "$OUT/cuda_tests.txt"
    stamp "tests: $(tail -n 1 "$OUT/cuda_tests.txt")"
fi
wait $datagen; stamp "dataset ($LONG_TASK): exit $?"

if [[ $ONLY_LONG != 1 ]]; then   # after the dataset: each speed run has the machine to itself
    small="dataset.n_episodes=12 algo.params.initial_replay_size=1000 algo.params.cuda_graph=true"
    speed() {  # speed NAME ALGO [OVERRIDES...]: one graphed run alone on the GPU
        local name=$1 algo=$2; shift 2
        $PY benchmarks/train_speed.py --algo "$algo" --seconds "$SPEED_S" --groups cuda:1 -- $small "$@" \
            > "$OUT/train_speed_$name.txt" 2>&1
        stamp "train_speed $name: $(grep -E '^cudax1' "$OUT/train_speed_$name.txt")"
    }
    speed lsiq lsiq
    speed iqlearn iqlearn
    speed sqil sqil
    speed lsiqfo lsiq algo.name=lsiqfo
fi

if [[ $MPS == 1 ]]; then
    source "$(dirname "$0")/mps.sh"   # start_mps, stop_mps
    if start_mps > "$OUT/mps.txt" 2>&1; then mps_on=1; else mps_on=0; fi
    stamp "$(grep '^MPS:' "$OUT/mps.txt" | tail -n 1)"
fi
if [[ -n $END_BY ]]; then LONG_S=$(( END_BY - SECONDS )); fi   # END_BY replaces LONG_S
stamp "long runs: $LONG_TASK $LONG_ALGO $LONG_NAME, seeds $LONG_SEEDS, ${LONG_S} s"
# graphed runs of $LONG_ALGO (default: LS-IQ with the README's Hopper setting), the seeds side by side (a run dir already in $RUNS resumes)
pids=()
for seed in $LONG_SEEDS; do
    timeout -s TERM "$LONG_S" $PY train.py task="$LONG_TASK" algo="$LONG_ALGO" seed="$seed" n_steps=1500000 \
        eval.every=5000 checkpoint_every=25000 results_dir="$RUNS" logger=csv device=cuda \
        algo.params.cuda_graph=true $LONG_OVERRIDES name="$LONG_NAME" > "$RUNS/seed$seed.out" 2>&1 &
    pids+=($!)
done
wait "${pids[@]}"
stamp "long runs done"
if [[ ${mps_on:-0} == 1 ]]; then stop_mps; fi
(cd "$RUNS" && tar czf "$OUT/lsiq_runs.tar.gz" --exclude='*.pt' --exclude=wandb .)
stamp "end"
