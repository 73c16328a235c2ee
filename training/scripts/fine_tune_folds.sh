#!/usr/bin/env bash
# Five minutes of a validation car's own drives of the scored kinds: the fine-tune from
# D1 with its epoch count chosen on the 20 % validation split (the handover until now)
# and by 5-fold cross-validation over the bags (--folds 5), against the same network
# trained from scratch (split; and --folds 5 on cars 0 and 1). Scored on the car's 18
# benchmark-style validation drives as the node runs them (mirror-averaged).
# docs/evaluation/fine-tune-folds. One car per call, one core, 25-45 minutes:
#     bash training/scripts/fine_tune_folds.sh CAR [OUT]
set -euo pipefail
c=$1
D=${2:-data/cvcurve}
START=${START:-data/runs/o5u-dist.safetensors}   # D1, a member of fleet_ukf_ensemble_disturbance
export OMP_NUM_THREADS=1
mkdir -p "$D"
[ -d "data/mid/car$c/min5" ] || .venv/bin/python training/scripts/fleet_scenarios.py --cars 25 \
    --seed 2 --only "$c" --per-car 32 --families scen1 scen2 scen3 scen4 step_steer \
    sweep_steer --out "data/mid/car$c/min5" > /dev/null
[ -d "data/spec/car$c/test" ] || .venv/bin/python training/scripts/validation_benchmark.py \
    --cars "$c" --out "data/spec/car$c/test" > /dev/null
source training/scripts/fine_tune_recipe.sh
train "$D/car$c" "data/mid/car$c/min5" ft --init "$START" --learning-rate 3e-4
train "$D/car$c" "data/mid/car$c/min5" ftcv --init "$START" --learning-rate 3e-4 --folds 5
train "$D/car$c" "data/mid/car$c/min5" scratch "${S[@]}"
if [ "$c" -le 1 ]; then train "$D/car$c" "data/mid/car$c/min5" scratchcv "${S[@]}" --folds 5; fi
models=("$START" "$D/car$c-ft.safetensors" "$D/car$c-ftcv.safetensors" "$D/car$c-scratch.safetensors")
[ -f "$D/car$c-scratchcv.safetensors" ] && models+=("$D/car$c-scratchcv.safetensors")
.venv/bin/python training/scripts/crossfall_training_check.py --model "${models[@]}" \
    --data "data/spec/car$c/test" --out "$D/cvscore-car$c.json" > "$D/cvscore-car$c.log" 2>&1
