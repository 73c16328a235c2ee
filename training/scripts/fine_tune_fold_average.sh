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
source training/scripts/fine_tune_recipe.sh
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
    train "$D/car$c" "$drives" lr1e-3-folds --init "$START" --learning-rate 1e-3 --folds 5 \
        --refit no
    ;;
esac
merge_and_score "$D/$c-foldavg" "$drives" "$scored" "$run"/folds/fold-*.safetensors
