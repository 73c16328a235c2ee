#!/usr/bin/env bash
# Fine-tuning measurement (docs/training.md, "Fine-tuning"): the shipped fleet_lstm_paper
# on compact_rwd, a car outside its training fleet: zero-shot, fine-tuned with the
# model's statistics kept or refitted, and the same network trained from scratch, each
# on the same ~5 min of randomized driving (29 runs, mu 0.3-1.0), scored on 12 other
# randomized runs of the car (other seed). CPU, about 15 minutes on 2 cores.
set -euo pipefail
OUT=${1:-data/fine-tune}
BIN=.venv/bin
mkdir -p "$OUT"
$BIN/sideslip-generate --preset randomized --vehicle compact_rwd --count 29 --seed 101 \
    --noise paper --out "$OUT/train" --quiet --force
$BIN/sideslip-generate --preset randomized --vehicle compact_rwd --count 12 --seed 202 \
    --noise paper --out "$OUT/test" --quiet --force
TRAIN=("$BIN/sideslip-train" --data "$OUT/train" --profile quick --device cpu --quiet --force)
OMP_NUM_THREADS=1 "${TRAIN[@]}" --init fleet_lstm_paper --out "$OUT/keep.safetensors" &
OMP_NUM_THREADS=1 "${TRAIN[@]}" --init fleet_lstm_paper --normalization refit \
    --out "$OUT/refit.safetensors" &
wait
OMP_NUM_THREADS=2 "${TRAIN[@]}" --model lstm --features paper_kinematic --prior kinematic_window \
    --hidden-units 32 --out "$OUT/scratch.safetensors"
SHIPPED=sideslip_estimator/sideslip_estimator/data/models/fleet_lstm_paper.safetensors
$BIN/sideslip-evaluate --model "$SHIPPED" "$OUT/keep.safetensors" "$OUT/refit.safetensors" \
    "$OUT/scratch.safetensors" --data "$OUT/test" --out "$OUT/report" --force \
    --title "fleet_lstm_paper on compact_rwd: zero-shot, fine-tuned (keep, refit), scratch"
