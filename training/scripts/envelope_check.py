"""Which cars lie inside a model's training-car envelope (``ModelMetadata.envelope``).

Judged by parameters only (no scoring): the six held-out cars, the cars of a fleet
draw (e.g. the validation fleet) and named simulator vehicles, each with the
quantities that lie outside, as the estimator reports them.

    python training/scripts/envelope_check.py fleet_ukf_measurable --held-out \\
        --fleet 100 2 --vehicle paper_sedan compact_rwd
"""

from __future__ import annotations

import argparse
import sys

from sideslip_msgs_py.artifact import read_artifact
from sideslip_msgs_py.fleet_envelope import FleetEnvelope
from sideslip_sim.held_out import held_out_vehicles
from sideslip_sim.presets import fleet
from sideslip_sim.vehicle import VehicleParams, load_vehicle, vehicle_record
from sideslip_training.init_model import resolve
from sideslip_training.physics_params import nominal_parameters


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("model", help="a model file or a shipped model's name")
    parser.add_argument("--held-out", action="store_true", help="the six held-out cars")
    parser.add_argument(
        "--fleet", nargs=2, type=int, metavar=("COUNT", "SEED"), help="a fleet draw"
    )
    parser.add_argument("--vehicle", nargs="*", default=[], help="simulator vehicles by name")
    args = parser.parse_args(argv)
    _, meta = read_artifact(resolve(args.model))
    if meta.envelope is None:
        print(f"{args.model}: records no envelope", file=sys.stderr)
        return 2
    envelope = FleetEnvelope.from_dict(meta.envelope)
    cars: list[VehicleParams] = []
    if args.held_out:
        cars += held_out_vehicles().values()
    if args.fleet:
        cars += list({r.vehicle.name: r.vehicle for r in fleet(*args.fleet)}.values())
    cars += [load_vehicle(name) for name in args.vehicle]
    inside = 0
    for car in cars:
        outside = envelope.outside(nominal_parameters("ukf", vehicle_record(car)), car.name)
        inside += not outside
        print(f"{car.name:28s} {'inside' if not outside else 'OUTSIDE: ' + '; '.join(outside)}")
    print(f"{inside} of {len(cars)} cars inside {args.model}'s {envelope.cars} training cars")
    return 0


if __name__ == "__main__":
    sys.exit(main())
