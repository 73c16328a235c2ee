#!/usr/bin/env bash
# Two variants of fine_tune_folds.sh's fine-tune, on the same validation car, data and
# scoring (docs/evaluation/fine-tune-folds, "Two variants"):
#   lr1e-3    D1 with --folds 5 at learning rate 1e-3 instead of 3e-4
#   e40       D1 with --folds 5 at 3e-4, up to 40 epochs instead of 20
#   lr1e-3-e40  D1 with --folds 5 at 1e-3, up to 40 epochs instead of 20
#   ensemble  all five members of fleet_ukf_ensemble_disturbance, member by member, for
#             the epoch count D1's --folds 5 chose on the car (--epochs N, read from
#             fine_tune_folds.sh's run folder)
# One car and variant per call, one core; lr1e-3 16-20 minutes, e40 35, lr1e-3-e40 about 35, ensemble 32:
#     bash training/scripts/fine_tune_variants.sh CAR VARIANT [OUT] [FOLDS_OUT]
set -euo pipefail
c=$1
variant=$2
D=${3:-data/ftvar}
CV=${4:-data/cvcurve}   # fine_tune_folds.sh's outputs (its run first)
export OMP_NUM_THREADS=1
mkdir -p "$D"
O=(--profile quick --stride 5 --device cpu --workers 1 --quiet)
out="$D/car$c-$variant.safetensors"
case $variant in
    lr1e-3)
        args=(--init data/runs/o5u-dist.safetensors --learning-rate 1e-3 --folds 5
              --max-epochs 20) ;;
    e40)
        args=(--init data/runs/o5u-dist.safetensors --learning-rate 3e-4 --folds 5
              --max-epochs 40) ;;
    lr1e-3-e40)
        args=(--init data/runs/o5u-dist.safetensors --learning-rate 1e-3 --folds 5
              --max-epochs 40) ;;
    ensemble)
        n=$(.venv/bin/python -c "import json,sys; print(json.load(open(sys.argv[1]))['epochs'])" \
            "$CV/car$c-ftcv.run/cross_validation.json")
        [ "$n" -ge 1 ] || { echo "D1 kept its start on car $c: nothing to train" >&2; exit 1; }
        args=(--init fleet_ukf_ensemble_disturbance --learning-rate 3e-4 --epochs "$n") ;;
    *) echo "unknown variant $variant (lr1e-3, e40, lr1e-3-e40, ensemble)" >&2; exit 2 ;;
esac
[ -f "$out" ] || /usr/bin/time -f "$variant %e s" .venv/bin/sideslip-train \
    --data "data/mid/car$c/min5" "${args[@]}" "${O[@]}" --out "$out" > "$D/car$c-$variant.log" 2>&1
models=("$out")
[ "$variant" = ensemble ] && models+=(fleet_ukf_ensemble_disturbance)
.venv/bin/python training/scripts/crossfall_training_check.py --model "${models[@]}" \
    --data "data/spec/car$c/test" --out "$D/score-car$c-$variant.json" > "$D/score-car$c-$variant.log" 2>&1
