#!/usr/bin/env bash
# The UR10e LSTM tables of model-export/README.md ("UR10e (real logs)"): identify on five
# Fourier runs, one dataset per run, train the `paper` network (both output forms) and the
# `feedforward` preset on seven runs (validated on an eighth), evaluate on two held-out runs.
# Usage: bash scripts/ur10e_lstm.sh OUT_DIR   (data: $DATASETS_DIR/ur10e, default
# ../shared/datasets/ur10e beside the workspace; nothing is copied into the project).
# Environment (optional): EPOCHS (60), the training epochs of every network.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
out="${1:?usage: ur10e_lstm.sh OUT_DIR}"
D="${DATASETS_DIR:-$root/../shared/datasets}/ur10e"
I="$D/identification"
[ -d "$I" ] || { echo "no UR10e data at $D (set DATASETS_DIR)" >&2; exit 2; }
cargo build --profile host -p model-export --manifest-path "$root/Cargo.toml" --quiet
ME="$root/target/host/model-export"
mkdir -p "$out/data"
cd "$out"
log() { printf -- "--log %s " "$@"; }
fit=(20_02_12-50sec_12harm 20_02_12-40sec_12harm 20_02_19_14harm50sec 20_02_06-20sec_10harm 20_02_06-20sec_5harm)
more=(20_02_05-20sec_8harm 20_02_10-20sec_7harm)
val=20_02_05-20sec_12harm
tests=(20_02_19_15harm50sec 20_02_10-30sec_12harm)
# shellcheck disable=SC2046
"$ME" identify --robot "$D/ur10e.urdf" --layout ur10e $(for f in "${fit[@]}"; do log "$I/ur-$f.csv"; done) \
  --validation-log "$I/ur-${tests[0]}.csv" --coulomb-smoothing-rad-s 0.02 -o model.json > identify.txt
for f in "${fit[@]}" "${more[@]}" "$val" "${tests[@]}"; do
  "$ME" torque --robot "$D/ur10e.urdf" --identified model.json --layout ur10e --log "$I/ur-$f.csv" \
    --dataset --trim-rest-rad-s 0 --torque-cutoff-hz 0 -o "data/$f.csv" > /dev/null
done
train=$(for f in "${fit[@]}" "${more[@]}"; do printf "data/%s.csv," "$f"; done)
for form in next increment feedforward; do
  case $form in
    next) p=(--preset paper) ;;
    increment) p=(--preset paper --paper-output increment) ;;
    feedforward) p=(--preset feedforward) ;;
  esac
  "$ME" train --data "${train%,}" --validation-data "data/$val.csv" "${p[@]}" --joints 1,2,3,4,5,6 \
    --epochs "${EPOCHS:-60}" --lr 0.003 --seed 1 --quiet --out "lstm_$form.safetensors" \
    --loss-plot "loss_$form.svg" --report "train_$form.json" > "train_$form.txt"
  for t in "${tests[@]}"; do
    echo "== $form on $t"
    "$ME" evaluate --network "lstm_$form.safetensors" --data "data/$t.csv" "${p[@]}" \
      --joints 1,2,3,4,5,6 --report "eval_${form}_$t.json"
  done
done
