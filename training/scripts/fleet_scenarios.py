"""The training fleet's cars driving the paper's Table 4 scenarios (DLC + sine steer, DLC +
cornering, continuous sine steer, random steer), which the fleet preset's drives never
combine: an experiment on whether the kind of driving, not the cars, is what the
`measurable` networks lack on benchmark-style drives (docs/evaluation/scenario-driving).

Each car of ``sample_fleet(COUNT, SEED)`` (the cars of ``sideslip-generate --preset
fleet --count 4·COUNT --seed SEED``) drives ``--per-car`` scenarios, each drawn with its
own road μ (0.3-1.0), speed (the table's ±20 %), steering severity (0.5-0.95 of the
μ-limited lateral acceleration) and random-steer seed (never a benchmark's). Paper noise.

    python training/scripts/fleet_scenarios.py --cars 100 --seed 1 --out data/fleet-scen

``--held-out NAME`` drives one held-out car instead (a user's own five minutes of it for
the fine-tuning measurement, docs/evaluation/fine-tune-folds): the drives are of the
benchmark's kinds but never at its μ, speeds, random-steer seeds or noise draws.
"""

from __future__ import annotations

import argparse
import sys
import zlib
from pathlib import Path

import numpy as np

from sideslip_sim.fleet import sample_fleet
from sideslip_sim.generate import generate, prepare_output
from sideslip_sim.held_out import HELD_OUT_NAMES, held_out_digests, held_out_vehicles
from sideslip_sim.maneuvers import Maneuver, auto_stl_amplitude
from sideslip_sim.presets import HELD_OUT_SPEED_KMH, TABLE4, VehicleRun
from sideslip_sim.single_track import SingleTrack
from sideslip_sim.tire import load_tire

# The benchmark's random-steer seeds are 1100-1105 (presets._TEST_SEED_OFFSET + 100 + j).
_FIRST_SEED = 10_000


# The benchmark's step steer and sine sweep (its speed, 300 N m · μ, 10 s, as
# presets.benchmark_runs drives them), as drawn here.
_OTHER = {family: (speed, 300.0, 10.0) for family, speed in HELD_OUT_SPEED_KMH.items()}


def scenario_runs(
    cars: int, seed: int, per_car: int, families: tuple[str, ...] = tuple(TABLE4),
    only: int | None = None, held_out: str | None = None,
) -> list[VehicleRun]:  # fmt: skip
    """``per_car`` drives of each car (or of the ``only``-th car) of the fleet draw, or of
    the held-out car named ``held_out`` (a user's own drives of it: the benchmark's kinds,
    never its μ, speeds or seeds)."""
    if held_out is not None:
        chosen = [held_out_vehicles()[held_out]]
        # A stream of its own: crc32 of the name, stable across runs and interpreters.
        rng = np.random.default_rng([seed, 0x5CE4, 0x4E0, zlib.crc32(held_out.encode())])
    else:
        fleet = sample_fleet(cars, seed, exclude_digests=held_out_digests()).vehicles
        chosen = fleet if only is None else [fleet[only]]
        rng = np.random.default_rng([seed, 0x5CE4] if only is None else [seed, 0x5CE4, only])
    runs = []
    for car in chosen:
        model = SingleTrack.from_vehicle(car, load_tire(str(car.tire_path())))
        for i in range(per_car):
            family = str(rng.choice(families))
            scenario = family in TABLE4
            speed, torque, duration = TABLE4[family][1:] if scenario else _OTHER[family]
            mu = float(np.round(rng.uniform(0.3, 1.0), 3))
            speed = float(np.round(speed * rng.uniform(0.8, 1.2), 1))
            ay = float(np.round(rng.uniform(0.5, 0.95), 3))
            amplitude = auto_stl_amplitude(car, model, speed / 3.6, mu, ay) if scenario else 0.0
            m = Maneuver(
                f"{car.name}_s{i}_{family}", "scenario" if scenario else family, duration,
                speed, torque * mu, scenario=family if scenario else "", mu=mu,
                seed=int(rng.integers(_FIRST_SEED, 2**31 - 1)), ay_fraction=ay,
                stl_amplitude_m=amplitude,
            )  # fmt: skip
            runs.append(VehicleRun(car, m))
    return runs


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cars", type=int, default=100, help="cars of the fleet draw")
    p.add_argument("--seed", type=int, default=1, help="the fleet draw's seed (1: fleet-train)")
    p.add_argument("--per-car", type=int, default=2)
    p.add_argument(
        "--families",
        nargs="+",
        default=list(TABLE4),
        choices=[*TABLE4, *_OTHER],
        help="drawn from (default: the Table 4 scenarios)",
    )
    p.add_argument("--only", type=int, metavar="K", help="only the K-th car of the draw")
    p.add_argument(
        "--held-out", choices=HELD_OUT_NAMES, help="drive this held-out car instead of the fleet's"
    )
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--jobs", type=int, default=2)
    args = p.parse_args(argv)
    runs = scenario_runs(
        args.cars, args.seed, args.per_car, tuple(args.families), args.only, args.held_out
    )
    prepare_output(args.out, force=True)
    generate(runs, args.out, noise="paper", seed=args.seed, preset_name="fleet-scenarios",
             jobs=args.jobs)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
