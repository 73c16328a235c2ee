"""A ``sideslip-train --folds K`` model's σ calibrated again, on the out-of-fold errors of
its run's fold networks (``RUN/folds/fold-K.safetensors``), written as a copy
of the model: the calibration ``--folds`` makes (:mod:`sideslip_training.fold_calibration`)
for runs made before it did, to compare with the validation split's on the same weights.

The folds are dealt again from the run's recorded command (the same bags and seed deal
the same folds). docs/evaluation/fine-tune-folds, "Intervals out of fold".

    python training/scripts/fold_calibration_check.py --run data/foldavg/car2-lr1e-3-folds.run \\
        --model data/ftvar/car2-lr1e-3.safetensors --out data/oofcal/car2-oof.safetensors
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Any

from sideslip_msgs_py.artifact import read_artifact, write_artifact
from sideslip_training.cli import _cv_runs
from sideslip_training.cross_validation import fold_runs
from sideslip_training.export import load_model
from sideslip_training.train_args import train_parser
from sideslip_training.train_intervals import calibrate_selection, interval_mode
from sideslip_training.train_plan import plan_training


def dealt_again(run: Path) -> tuple[argparse.Namespace, Any, list[list[Any]]]:
    """The --folds run's options, its plan (data loaded, nothing written) and its folds,
    from the command its run folder records."""
    command = json.loads((run / "config.json").read_text())["command"]
    train_argv = shlex.split(command)[1:]
    with tempfile.TemporaryDirectory() as tmp:
        train_argv[train_argv.index("--out") + 1] = str(Path(tmp) / "unused.safetensors")
        targs = train_parser().parse_args([*train_argv, "--force"])
        plan = plan_training(targs, lambda m: print(m, file=sys.stderr))
    groups = fold_runs(_cv_runs(plan), targs.folds, plan.data.split, targs.seed)
    return targs, plan, groups


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run", type=Path, required=True, help="the --folds run folder")
    p.add_argument("--model", type=Path, required=True, help="the model whose σ to replace")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    targs, plan, groups = dealt_again(args.run)
    nets = [
        load_model(args.run / "folds" / f"fold-{k + 1}.safetensors")[0] for k in range(len(groups))
    ]
    _, meta = load_model(args.model)
    unc, figures = calibrate_selection(
        interval_mode(targs.intervals, plan, groups),
        plan,
        None,
        replace(meta, uncertainty=None),
        targs.seed,
        lambda m: print(m, file=sys.stderr),
        targs.intervals,
        folds=list(zip(groups, nets, strict=True)),
    )
    if unc is None or figures is None:
        print("no calibration", file=sys.stderr)
        return 1
    tensors, _ = read_artifact(args.model)
    metrics = {**meta.metrics, "interval_calibration": figures}
    write_artifact(args.out, tensors, replace(meta, uncertainty=unc, metrics=metrics), force=True)
    print(f"wrote {args.out}: scale {unc['scale']:.3f}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
