"""Per μ cell, the share of a validation car's benchmark samples inside ±1.96 σ for ways
of calibrating a ``--folds`` fine-tune's σ from the same errors, on the same weights:

- ``split``: the model's own σ (its start's terms, the scale from its validation split);
- ``oof-scale``: the start's terms, the scale from every bag out of fold (what
  ``sideslip-train --folds`` does);
- ``oof-fit-all``: terms by likelihood and scale both on all the out-of-fold errors;
- ``oof-fit-halves``: terms on half the bags' out-of-fold errors, the scale on the
  other half (``--intervals fit`` with folds).

Offline, from :class:`~sideslip_training.calibrate.Errors`: the figures equal
``sideslip-evaluate``'s coverage (checked on cars 0 and 1). Writes ``--out`` (JSON).
docs/evaluation/fine-tune-folds, "Intervals out of fold".

    python training/scripts/fold_calibration_variants.py --run data/foldavg/car2-lr1e-3-folds.run \\
        --model data/ftvar/car2-lr1e-3.safetensors --data data/spec/car2/test --out car2.json
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from fold_calibration_check import dealt_again

from sideslip_msgs_py.data_source import mirror_average_on
from sideslip_msgs_py.uncertainty import Uncertainty
from sideslip_training.calibrate import (
    Errors,
    calibrate,
    conformal_scale,
    fit_coefficients,
    z_of,
)
from sideslip_training.dataset import load_runs
from sideslip_training.export import load_model
from sideslip_training.fold_calibration import out_of_fold_errors
from sideslip_training.train_intervals import _start_sigma


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run", type=Path, required=True, help="the --folds run folder (folds/)")
    p.add_argument("--model", type=Path, required=True, help="the refit, with its split's σ")
    p.add_argument("--data", type=Path, required=True, help="the car's benchmark drives")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    model, meta = load_model(args.model)
    mirror = mirror_average_on("auto", meta.provenance)
    targs, plan, groups = dealt_again(args.run)
    folder = args.run / "folds"
    nets = [load_model(folder / f"fold-{k + 1}.safetensors")[0] for k in range(len(groups))]
    spec = plan.spec
    car = {"vehicle": spec.vehicle, "observer_params_file": spec.observer_params_file,
           "car": spec.car, "mirror_average": mirror}  # fmt: skip
    start = _start_sigma(plan, meta, car, lambda _: None)
    runs, oof = out_of_fold_errors(
        list(zip(groups, nets, strict=True)), replace(meta, uncertainty=start.to_dict()), car
    )
    scored, _ = load_runs([args.data])
    test = Errors.of_runs(scored, model, meta, mirror_average=mirror)
    mu = [re.search(r"_mu(\d\d)_", r.name).group(1) for r in scored]  # type: ignore[union-attr]
    fit = Uncertainty.from_dict(meta.uncertainty).fit_range

    coefficients = fit_coefficients(oof)
    halves, _ = calibrate(runs, None, replace(meta, uncertainty=None), errors=oof, seed=targs.seed)
    variants = {
        "split": Uncertainty.from_dict(meta.uncertainty),
        "oof-scale": Uncertainty(
            start.coefficients, conformal_scale(oof, start.coefficients, 0.95), 0.95, fit_range=fit
        ),
        "oof-fit-all": Uncertainty(
            coefficients, conformal_scale(oof, coefficients, 0.95), 0.95, fit_range=fit
        ),
        "oof-fit-halves": replace(halves, fit_range=fit),
    }
    table = {}
    for name, unc in variants.items():
        inside = np.abs(test.err) <= z_of(0.95) * np.sqrt(test.variance(unc))
        cells = {
            f"{int(m) / 10:.1f}": float(
                inside[np.isin(test.run, [i for i, x in enumerate(mu) if x == m])].mean()
            )
            for m in sorted(set(mu), reverse=True)
        }
        table[name] = {"scale": unc.scale, "coefficients": list(unc.coefficients), "cells": cells}
        shown = ", ".join(f"μ {k}: {v:.3f}" for k, v in cells.items())
        print(f"{name:15s} scale {unc.scale:.3f}  {shown}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(table, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
