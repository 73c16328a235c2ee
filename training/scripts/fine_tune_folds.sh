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
O=(--profile quick --stride 5 --max-epochs 20 --device cpu --workers 1 --quiet)
S=(--model lstm --hidden-units 64 --features measurable_observer_signals --prior ukf
   --observer-value estimate_disturbance=true)
run() {
    local name=$1
    shift
    [ -f "$D/car$c-$name.safetensors" ] && return
    /usr/bin/time -f "$name %e s" .venv/bin/sideslip-train --data "data/mid/car$c/min5" "$@" \
        "${O[@]}" --out "$D/car$c-$name.safetensors" > "$D/car$c-$name.log" 2>&1
}
run ft --init "$START" --learning-rate 3e-4
run ftcv --init "$START" --learning-rate 3e-4 --folds 5
run scratch "${S[@]}"
if [ "$c" -le 1 ]; then run scratchcv "${S[@]}" --folds 5; fi
models=("$START" "$D/car$c-ft.safetensors" "$D/car$c-ftcv.safetensors" "$D/car$c-scratch.safetensors")
[ -f "$D/car$c-scratchcv.safetensors" ] && models+=("$D/car$c-scratchcv.safetensors")
.venv/bin/python training/scripts/crossfall_training_check.py --model "${models[@]}" \
    --data "data/spec/car$c/test" --out "$D/cvscore-car$c.json" > "$D/cvscore-car$c.log" 2>&1
