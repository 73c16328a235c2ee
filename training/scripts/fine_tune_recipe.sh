# Sourced by the fine_tune_*.sh scripts: the recipe of docs/evaluation/fine-tune-folds
# (quick profile at stride 5, 20 epochs at most, one core) and the network trained from
# scratch beside it, and `train`, which runs one training unless its model is there:
#     train PREFIX DRIVES NAME [sideslip-train options...]   # -> PREFIX-NAME.safetensors
O=(--profile quick --stride 5 --max-epochs 20 --device cpu --workers 1 --quiet)
S=(--model lstm --hidden-units 64 --features measurable_observer_signals --prior ukf
   --observer-value estimate_disturbance=true)
train() {
    local prefix=$1 drives=$2 name=$3
    shift 3
    [ -f "$prefix-$name.safetensors" ] && return
    /usr/bin/time -f "$name %e s" .venv/bin/sideslip-train --data "$drives" "$@" \
        "${O[@]}" --out "$prefix-$name.safetensors" > "$prefix-$name.log" 2>&1
}
# merge_and_score PREFIX DRIVES SCORED MODEL...: the models averaged (sideslip-merge, into
# PREFIX.safetensors unless there) and scored on SCORED as the node runs them
# (PREFIX-score.json). σ is calibrated on four of DRIVES, the car's own drives: the merge
# needs some, and the MAE does not depend on them.
merge_and_score() {
    local prefix=$1 drives=$2 scored=$3
    shift 3
    local cal=$prefix-cal
    if [ ! -d "$cal" ]; then
        mkdir -p "$cal"
        for b in $(ls -d "$drives"/*/ | head -4); do ln -s "$PWD/$b" "$cal/"; done
    fi
    [ -f "$prefix.safetensors" ] || .venv/bin/sideslip-merge "$@" --data "$cal" \
        --out "$prefix.safetensors" > "$prefix-merge.log" 2>&1
    .venv/bin/python training/scripts/crossfall_training_check.py --model "$prefix.safetensors" \
        --data "$scored" --out "$prefix-score.json" > "$prefix-score.log" 2>&1
}
