"""The UKF with and without its lateral disturbance state (``ukf.estimate_disturbance``) on
level and banked roads: pooled MAE [deg] per car of the ``ukf`` back-end with the car's
true file, every run from a fresh filter through the estimator core, for each settings
variant (docs/evaluation/road-bank).

    python training/scripts/ukf_disturbance_check.py --data data/val-benchmark-bank2.5 \
        --cars 8 --variants '{"off": {}, "on": {"estimate_disturbance": true}}' --out v.json

``--start-at F``: each run's filter starts at that fraction of the run, in mid-manoeuvre
(as a restart after a gap, or a recording cut in time), and is scored from there.

``--cars N``: the first N cars of the validation fleet (``fit_bags_check.VAL_CARS``; the
bags of ``validation_benchmark.py`` or ``sideslip-generate --preset fleet --count 100
--seed 2``); ``--held-out``: the six held-out cars instead (scored once).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from sideslip_estimator.backends import create_backend
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_estimator.replay import replay, replay_columns
from sideslip_msgs_py.bag import read_bag
from sideslip_sim.fleet import sample_fleet
from sideslip_sim.held_out import held_out_digests, held_out_vehicles
from sideslip_training.dataset import slice_samples

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_check import VAL_CARS, VAL_SEED
from held_out_fit import write_true_ukf

WINDOW = 100


def _pooled_mae(drives, ukf_file: Path, values: dict) -> float:
    errors = []
    for samples in drives:
        backend = create_backend("ukf", {"params_file": str(ukf_file), **values}, WINDOW)
        got = replay(Estimator(backend, EstimatorParams(WINDOW)), replay_columns(samples))
        errors.append(np.degrees(np.abs(got.beta_rad - samples.beta_rad())))
    return float(np.nanmean(np.concatenate(errors)))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, required=True)
    group = p.add_mutually_exclusive_group(required=True)
    group.add_argument("--cars", type=int, help="the first N validation cars")
    group.add_argument("--held-out", action="store_true", help="the six held-out cars")
    p.add_argument("--variants", required=True, help="JSON: {name: {ukf.* values}}")
    p.add_argument("--start-at", type=float, default=0.0, help="fraction of each run [0, 1)")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    if not 0.0 <= args.start_at < 1.0:
        p.error(f"--start-at must be in [0, 1), got {args.start_at}")
    variants = json.loads(args.variants)
    if args.held_out:
        cars = list(held_out_vehicles().values())
    else:
        fleet = sample_fleet(VAL_CARS, VAL_SEED, exclude_digests=held_out_digests()).vehicles
        cars = fleet[: args.cars]
    tmp = Path(tempfile.mkdtemp(prefix="ukf-disturbance-"))
    results: dict[str, dict[str, float]] = {name: {} for name in variants}
    for car in cars:
        ukf_file = write_true_ukf(car, tmp / f"{car.name}.yaml", "ukf_disturbance_check.py")
        bags = sorted(b for b in args.data.iterdir() if b.name.startswith(f"{car.name}_"))
        drives = [read_bag(b).samples for b in bags]
        drives = [slice_samples(d, int(args.start_at * len(d)), len(d)) for d in drives]
        for name, values in variants.items():
            results[name][car.name] = _pooled_mae(drives, ukf_file, values)
            print(car.name, name, f"{results[name][car.name]:.4f}", flush=True)
        args.out.write_text(json.dumps(results, indent=1))
    for name, per_car in results.items():
        print(f"{name}: mean over cars {np.mean(list(per_car.values())):.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
