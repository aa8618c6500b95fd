#!/usr/bin/env bash
# Do the SAC-based learners stay at the expert once they got there? A cheap, many-seed check on
# InvertedPendulum.balance.perfect (the shipped expert's 75 training episodes; expert 1000, random 5.4) with the
# off-policy learning test's small settings (tests/algorithms/test_offpolicy_learning.py: [64, 64] networks,
# 128 + 128 samples, critic lr 1e-3, actor lr 3e-4, tau 0.02, fixed temperature 0.01), 20k env steps, an evaluation
# (5 deterministic episodes) every 2500. One CSV per variant, resumable per seed (finished seeds are skipped),
# then the table of `il_baselines.py --summarize --stability 0.9`.
#
#   bash benchmarks/offpolicy_stability.sh                        # every variant below
#   bash benchmarks/offpolicy_stability.sh lsiq lsiq_mixture      # some of them
#   OUT=/tmp/stab SEEDS="0 1" bash benchmarks/offpolicy_stability.sh
set -euo pipefail
cd "$(dirname "$0")/.."

OUT=${OUT:-benchmarks/il_results/pendulum_stability}
SEEDS=${SEEDS:-0 1 2 3}
PYTHON=${PYTHON:-python}
SMALL="policy.hidden=[64,64] critic_hidden=[64,64] batch_size=128 expert_batch_size=128 initial_replay_size=500
       replay_capacity=20000 critic_lr=1e-3 actor_lr=3e-4 tau=0.02 init_alpha=0.01 learn_alpha=false"
declare -A ALGO=([iqlearn]=iqlearn [lsiq]=lsiq [lsiq_mixture]=lsiq [lsiq_no_absorbing]=lsiq [sqil]=sqil
           [sqil_learned_alpha]=sqil [iqlearn_ln]=iqlearn [sqil_ln]=sqil)
declare -A EXTRA=([iqlearn]="" [lsiq]="" [lsiq_mixture]="objective=mixture" [lsiq_no_absorbing]="treat_absorbing=false"
                  [sqil]="" [sqil_learned_alpha]="learn_alpha=true"  # SAC's temperature tuning from 0.01
                  [iqlearn_ln]="critic_layer_norm=true" [sqil_ln]="critic_layer_norm=true")  # LayerNorm critics
ORDER=(lsiq iqlearn lsiq_mixture lsiq_no_absorbing sqil sqil_learned_alpha iqlearn_ln sqil_ln)
VARIANTS=("$@")
[ ${#VARIANTS[@]} -eq 0 ] && VARIANTS=("${ORDER[@]}")

mkdir -p "$OUT"
csvs=()
for variant in "${VARIANTS[@]}"; do
  [ -n "${ALGO[$variant]:-}" ] || { echo "unknown variant '$variant'; one of: ${ORDER[*]}" >&2; exit 2; }
  # shellcheck disable=SC2086  # word splitting of the settings is intended
  "$PYTHON" benchmarks/il_baselines.py --task InvertedPendulum.balance --datasets perfect --seeds $SEEDS \
    --steps 20000 --eval-every 2500 --eval-episodes 5 --algos "${ALGO[$variant]}" \
    --set $SMALL ${EXTRA[$variant]} --out "$OUT/$variant.csv"
  csvs+=("$OUT/$variant.csv")
done
"$PYTHON" benchmarks/il_baselines.py --summarize "${csvs[@]}" --stability 0.9
