"""The ``ukf`` back-end's noise settings against each other on validation bags, each bag
replayed with its own recorded car (true nominal values, effective axles), as the
held-out benchmark gives the filter; or with one ``--params-file`` for all (paper-test).

Per settings: MAE and RMSE [deg] pooled over the samples that got an estimate, and the
number of cars (runs without a car) on which each is the better. ``--values`` names a
JSON file as ``python -m sideslip_training.ukf_tuning --out`` writes (``best_values``);
``defaults`` is the back-end's defaults.

    python training/scripts/ukf_noise_check.py --data data/fleet-val data/val-benchmark \
        --values defaults ukf-tuning-fleet.json --out ukf-noise-validation.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from sideslip_estimator.backends.ukf import UkfBackend
from sideslip_training.ukf_tuning import RECORDED, ReplayRun, load_replay_runs, replay

DEFAULTS = {p.name: p.default for p in UkfBackend.parameters}


def settings(spec: str) -> dict[str, object]:
    if spec == "defaults":
        return dict(DEFAULTS)
    return {**DEFAULTS, **json.loads(Path(spec).read_text())["best_values"]}


def errors(job: tuple[ReplayRun, dict[str, object]]) -> np.ndarray:
    run, values = job
    err = np.degrees(replay(run, values) - run.beta_rad)
    return err[np.isfinite(err)]


def car_of(name: str) -> str:
    # fleet bags: <car>_<index>_<manoeuvre>; benchmark bags: <car>_mu<μ>_<scenario>
    head = name.split("_mu")[0]
    parts = head.split("_")
    return "_".join(parts[:2]) if parts[0].startswith("fleet") else head


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", nargs="+", required=True, help="validation bags (never training)")
    p.add_argument("--values", nargs="+", default=["defaults"], help="'defaults' or JSON files")
    p.add_argument("--params-file", default=RECORDED, help="'recorded' (default) or one car")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--out", type=Path)
    args = p.parse_args(argv)
    runs = load_replay_runs(args.data, recorded=args.params_file == RECORDED)
    report: dict[str, object] = {"data": args.data, "params_file": args.params_file}
    per_car: dict[str, dict[str, float]] = {}
    with ProcessPoolExecutor(args.workers) as pool:
        for spec in args.values:
            values = settings(spec)
            if args.params_file != RECORDED:
                values["params_file"] = args.params_file
            errs = list(pool.map(errors, [(r, values) for r in runs], chunksize=4))
            pooled = np.concatenate(errs)
            sums: dict[str, list[float]] = {}
            for run, e in zip(runs, errs, strict=True):
                acc = sums.setdefault(car_of(run.name), [0.0, 0.0])
                acc[0] += float(np.abs(e).sum())
                acc[1] += e.size
            for car, (total, n) in sums.items():
                per_car.setdefault(car, {})[spec] = total / n
            figures = {
                "mae_deg": float(np.abs(pooled).mean()),
                "rmse_deg": float(math.sqrt(np.mean(pooled**2))),
                "samples": int(pooled.size),
            }
            report[spec] = figures
            print(f"{spec}: MAE {figures['mae_deg']:.4f}°, RMSE {figures['rmse_deg']:.4f}°")
    if len(args.values) == 2:
        a, b = args.values
        better = sum(v[b] < v[a] for v in per_car.values())
        print(f"{b} better than {a} on {better} of {len(per_car)} cars")
        report["cars_better"] = {"of": len(per_car), b: better}
    report["per_car_mae_deg"] = per_car
    if args.out:
        args.out.write_text(json.dumps(report, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
