#!/usr/bin/env bash
# The --folds 5 fine-tune at 1e-3 averaged (sideslip-merge) with the network trained from
# scratch on the same five minutes: two models trained apart from one car's drives. On a
# validation car (CAR = 0..7: fine_tune_variants.sh lr1e-3 and fine_tune_folds.sh's
# scratch, scored on its 18 benchmark-style validation drives) or, once chosen there, a
# held-out car (CAR = heldout_*: fine_tune_folds_held_out.sh's two models).
# docs/evaluation/fine-tune-folds.
#     bash training/scripts/fine_tune_with_scratch.sh CAR [OUT]
set -euo pipefail
c=$1
D=${2:-data/ftscratch}
export OMP_NUM_THREADS=1
mkdir -p "$D"
case $c in
heldout_*)
    models=("data/cvheld/$c-ftcv.safetensors" "data/cvheld/$c-scratch.safetensors")
    drives=data/mid/ho/$c/min5
    scored=data/ho-by-car/held-out/$c
    ;;
*)
    models=("data/ftvar/car$c-lr1e-3.safetensors" "data/cvcurve/car$c-scratch.safetensors")
    drives=data/mid/car$c/min5
    scored=data/spec/car$c/test
    ;;
esac
source training/scripts/fine_tune_recipe.sh
merge_and_score "$D/$c-ftscratch" "$drives" "$scored" "${models[@]}"
