#!/usr/bin/env bash
# sideslip-fit --bags on a validation car, the epoch count chosen out of fold (FOLDS=5,
# the default) or on the stretch before each recording's test part (FOLDS=1), against the
# recorded default fit (docs/models/fleet_ukf_ensemble/finetune-lr-validation.json: the
# same 5 minutes of own fleet-style driving, the same start fleet_ukf_ensemble at learning
# rate 3e-4). Written at --interpolate 1 and moved back to the start by
# fit_interpolation.py for α 0 / 0.25 / 0.5 / 1, scored on the car's 18 benchmark-style
# validation drives, as that file was. One car per call, one core:
#     bash training/scripts/fit_bags_folds.sh C [OUT]     # C: validation car index 0..7
#     FOLDS=1 bash training/scripts/fit_bags_folds.sh C data/fbc-split
set -euo pipefail
c=$1
D=${2:-data/fbc-folds}
FOLDS=${FOLDS:-5}
export OMP_NUM_THREADS=1
VB="data/val-benchmark-$c"
mkdir -p "$D"
[ -f "$VB/index.json" ] || .venv/bin/python training/scripts/validation_benchmark.py \
    --cars "$c" --out "$VB" --jobs 1 > /dev/null
extra="--learning-rate 3e-4 --interpolate 1"
[ "$FOLDS" = 1 ] || extra="$extra --folds $FOLDS"
.venv/bin/python training/scripts/fit_bags_check.py --cars "$c" --minutes 5 --val-data "$VB" \
    --start fleet_ukf_ensemble --fit-args "$extra" --out "$D" > "$D-$c.log" 2>&1
.venv/bin/python training/scripts/fit_interpolation.py --cars "$D"/fleet2_car00"$c" \
    --start fleet_ukf_ensemble --alphas 0 0.25 0.5 1 --drives "$VB" --out "$D/interp-$c.json"
