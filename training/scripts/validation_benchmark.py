"""The held-out benchmark's kind of driving on validation cars: the Table 4 scenarios,
a step steer and a sine sweep at μ 1.0, 0.7 and 0.4 (:func:`sideslip_sim.presets.
benchmark_runs`, paper noise), on cars of the validation fleet (``sideslip-generate
--preset fleet --count 100 --seed 2``; ``fit_bags_check.py``'s car indices). Other
drives of those cars than their fleet-style ones, for choices that the held-out
benchmark will score, made without it.

    python training/scripts/validation_benchmark.py --cars 0 1 2 3 4 5 6 7 --out data/val-benchmark

``--imu-frame body`` / ``--imu-position X Y``: the same drives read by an IMU in the body
frame or away from the CG (:mod:`sideslip_sim.imu_mounting`); ``--bank PCT``: on a road
falling to the right by PCT % (as ``sideslip-generate --bank``); ``--noise-seed N``: the
same drives with other draws of the sensor noise (0, the default, is the benchmark's).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sideslip_sim.fleet import sample_fleet
from sideslip_sim.generate import generate, prepare_output
from sideslip_sim.held_out import held_out_digests
from sideslip_sim.imu_mounting import ImuMounting
from sideslip_sim.presets import benchmark_runs, on_bank

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_check import VAL_CARS, VAL_SEED


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cars", type=int, nargs="+", required=True, help="validation car indices")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--imu-frame", choices=("level", "body"), default="level")
    p.add_argument("--imu-position", type=float, nargs=2, default=(0.0, 0.0), metavar=("X", "Y"))
    p.add_argument("--bank", type=float, default=0.0, metavar="PCT", help="road crossfall [%%]")
    p.add_argument("--noise-seed", type=int, default=0, help="seed of the sensor noise's draws")
    args = p.parse_args(argv)
    imu = ImuMounting(tuple(args.imu_position), args.imu_frame)
    fleet = sample_fleet(VAL_CARS, VAL_SEED, exclude_digests=held_out_digests()).vehicles
    runs = benchmark_runs({fleet[k].name: fleet[k] for k in args.cars})
    if args.bank:
        runs = [on_bank(r, args.bank) for r in runs]
    prepare_output(args.out, force=True)
    generate(runs, args.out, noise="paper", seed=args.noise_seed,
             preset_name="validation-benchmark", jobs=args.jobs, imu=imu)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
