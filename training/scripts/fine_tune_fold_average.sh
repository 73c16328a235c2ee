#!/usr/bin/env bash
# The --folds 5 fine-tune's five fold networks averaged (sideslip-merge) instead of the
# refit on all the bags: no training beyond the folds. On a validation car (CAR = 0..7,
# the recipe of fine_tune_variants.sh lr1e-3, scored on its 18 benchmark-style
# validation drives) or, once chosen there, a held-out car (CAR = heldout_*, the fold
# networks of fine_tune_folds_held_out.sh). docs/evaluation/fine-tune-folds.
#     bash training/scripts/fine_tune_fold_average.sh CAR [OUT]
set -euo pipefail
c=$1
D=${2:-data/foldavg}
START=${START:-data/runs/o5u-dist.safetensors}   # D1, a member of fleet_ukf_ensemble_disturbance
export OMP_NUM_THREADS=1
mkdir -p "$D"
case $c in
heldout_*)
    run=data/cvheld/$c-ftcv.run
    drives=data/mid/ho/$c/min5
    scored=data/ho-by-car/held-out/$c
    [ -d "$run/folds" ] || { echo "no fold networks in $run: run fine_tune_folds_held_out.sh $c"; exit 2; }
    ;;
*)
    run=$D/car$c-lr1e-3-folds.run
    drives=data/mid/car$c/min5
    scored=data/spec/car$c/test
    # The same training as fine_tune_variants.sh lr1e-3 (same seed: the same folds), with
    # no refit, for its fold networks.
    [ -d "$run/folds" ] || .venv/bin/sideslip-train --data "$drives" --init "$START" \
        --learning-rate 1e-3 --folds 5 --refit no --profile quick --stride 5 --max-epochs 20 \
        --device cpu --workers 1 --quiet --out "$D/car$c-lr1e-3-folds.safetensors" \
        > "$D/car$c-folds.log" 2>&1
    ;;
esac
# σ is calibrated on four of the car's own drives (the merge needs some; the MAE here
# does not depend on them).
cal=$D/$c-cal
if [ ! -d "$cal" ]; then
    mkdir -p "$cal"
    for b in $(ls -d "$drives"/*/ | head -4); do ln -s "$PWD/$b" "$cal/"; done
fi
[ -f "$D/$c-foldavg.safetensors" ] || .venv/bin/sideslip-merge "$run"/folds/fold-*.safetensors \
    --data "$cal" --out "$D/$c-foldavg.safetensors" > "$D/$c-merge.log" 2>&1
.venv/bin/python training/scripts/crossfall_training_check.py --model "$D/$c-foldavg.safetensors" \
    --data "$scored" --out "$D/score-$c.json" > "$D/score-$c.log" 2>&1
