#!/usr/bin/env bash
# Issue 9's fine-tuning measurement on a held-out car, scored once: five minutes of the
# car's own drives of the scored kinds (fleet_scenarios.py --held-out), the recipe the
# eight validation cars picked (docs/evaluation/fine-tune-folds: from D1, --folds 5 at
# learning rate 1e-3, quick profile, stride 5, 20 epochs at most), against the same
# network trained from scratch on the same drives (validation split) and D1 zero-shot.
# Scored on the car's 18 held-out benchmark drives as the node runs the models.
# One car per call, one core, 20-35 minutes:
#     bash training/scripts/fine_tune_folds_held_out.sh NAME [OUT]    # NAME: heldout_*
set -euo pipefail
n=$1
D=${2:-data/cvheld}
START=${START:-data/runs/o5u-dist.safetensors}   # D1, a member of fleet_ukf_ensemble_disturbance
export OMP_NUM_THREADS=1
mkdir -p "$D"
[ -d "data/mid/ho/$n/min5" ] || .venv/bin/python training/scripts/fleet_scenarios.py --seed 2 \
    --held-out "$n" --per-car 32 --families scen1 scen2 scen3 scen4 step_steer sweep_steer \
    --out "data/mid/ho/$n/min5" > /dev/null
[ -d data/held-out ] || .venv/bin/sideslip-generate --preset held-out --out data/held-out > /dev/null
T="data/ho-by-car/held-out/$n"
if [ ! -d "$T" ]; then
    mkdir -p "$T"
    for b in data/held-out/"$n"_*; do ln -s "$PWD/$b" "$T/"; done
fi
source training/scripts/fine_tune_recipe.sh
train "$D/$n" "data/mid/ho/$n/min5" ftcv --init "$START" --learning-rate 1e-3 --folds 5
train "$D/$n" "data/mid/ho/$n/min5" scratch "${S[@]}"
.venv/bin/python training/scripts/crossfall_training_check.py --model "$START" \
    "$D/$n-ftcv.safetensors" "$D/$n-scratch.safetensors" --data "$T" \
    --out "$D/score-$n.json" > "$D/score-$n.log" 2>&1
