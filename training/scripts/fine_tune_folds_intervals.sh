#!/usr/bin/env bash
# The --folds 5 fine-tune's σ calibrated out of fold (every drive, each scored by the fold
# network that did not train on it; what sideslip-train --folds does since 2026-12-07)
# instead of on its one-minute validation split, on the same weights; then the car's
# benchmark drives scored with both σ (sideslip-evaluate, for coverage_cells.py).
# A validation car (CAR = 0..7: the fold networks of fine_tune_fold_average.sh's
# training, the refit of fine_tune_variants.sh lr1e-3) or, once chosen there, a held-out
# car (CAR = heldout_*: fine_tune_folds_held_out.sh's run). docs/evaluation/fine-tune-folds.
#     bash training/scripts/fine_tune_folds_intervals.sh CAR
set -euo pipefail
c=$1
START=${START:-data/runs/o5u-dist.safetensors}
export OMP_NUM_THREADS=1
source training/scripts/fine_tune_recipe.sh
case $c in
heldout_*)
    run=data/cvheld/$c-ftcv.run
    if [ ! -d "$run/folds" ]; then  # trained before --folds kept them: the same folds again
        train "data/cvheld/$c" "data/mid/ho/$c/min5" ftcv-folds --init "$START" \
            --learning-rate 1e-3 --folds 5 --refit no
        run=data/cvheld/$c-ftcv-folds.run
    fi
    model=data/cvheld/$c-ftcv.safetensors
    scored=data/ho-by-car/held-out/$c
    out=data/cvheld-oof
    ;;
*)
    run=data/foldavg/car$c-lr1e-3-folds.run
    model=data/ftvar/car$c-lr1e-3.safetensors
    scored=data/spec/car$c/test
    out=data/oofcal
    c=car$c
    train data/foldavg/$c "data/mid/$c/min5" lr1e-3-folds --init "$START" \
        --learning-rate 1e-3 --folds 5 --refit no
    ;;
esac
mkdir -p "$out/cov/$c"
[ -f "$out/$c-oof.safetensors" ] || .venv/bin/python training/scripts/fold_calibration_check.py \
    --run "$run" --model "$model" --out "$out/$c-oof.safetensors" > "$out/$c-oof.log" 2>&1
.venv/bin/sideslip-evaluate --model "$model" "$out/$c-oof.safetensors" --data "$scored" \
    --out "$out/cov/$c/report" > "$out/cov/$c/log" 2>&1
