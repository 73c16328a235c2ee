"""Measurable models zero-shot on validation cars with the ``ukf`` file made from each
car's description alone, and with its true file: the choice between models for owners
who have only a description, made without the held-out cars.

For each car of ``validation_benchmark.py`` folders (fleet-val cars driven the held-out
way: 18 runs per car), the description an owner can look up (``held_out_fit.
description``) gives the described ``ukf`` file (``sideslip-fit``'s, the fleet's
typical tyres); every model is scored on the car's runs with that file and with the
car's true one (``sideslip-evaluate``, pooled MAE per car).

    python training/scripts/described_validation.py --model A.safetensors B.safetensors \
        --data data/val-benchmark data/val-benchmark-2 --out data/described-validation

``--held-out`` takes the cars from ``sideslip_sim.held_out`` instead (``--data
data/held-out``: the held-out benchmark, for a model chosen before, scored once);
``--identified DIR`` adds a third file per car, ``DIR/CAR/identified-5min.ukf.yaml`` (as
``held_out_fit.py --zero-shot --identify 5`` writes it); ``--files`` scores with some of
the files only (e.g. ``--files described`` for a model already scored with the true ones).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import yaml

from sideslip_sim.fleet import sample_fleet
from sideslip_sim.held_out import held_out_digests, held_out_vehicles
from sideslip_training.evaluate_cli import main as evaluate_main
from sideslip_training.fit import Description

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_check import VAL_CARS, VAL_SEED
from held_out_fit import description, observer_file_args, pooled_mae, write_true_ukf


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", nargs="+", type=Path, required=True, help=".safetensors files")
    p.add_argument("--data", nargs="+", type=Path, required=True)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--held-out", action="store_true", help="the held-out cars' runs")
    p.add_argument("--identified", type=Path, help="folder of identified-axle ukf files")
    p.add_argument(
        "--files",
        nargs="+",
        choices=("described", "true", "identified"),
        help="score with these car files only (default: described, true, and identified "
        "with --identified)",
    )
    args = p.parse_args(argv)
    tags = args.files or ["described", "true", *([] if args.identified is None else ["identified"])]
    if "identified" in tags and args.identified is None:
        p.error("--files identified needs --identified DIR")
    if args.held_out:
        fleet = held_out_vehicles()
    else:
        fleet = {
            v.name: v
            for v in sample_fleet(VAL_CARS, VAL_SEED, exclude_digests=held_out_digests()).vehicles
        }
    bags_of: dict[str, list[str]] = defaultdict(list)
    for folder in args.data:
        for run in json.loads((folder / "index.json").read_text())["runs"]:
            bags_of[run["vehicle"]].append(str(folder / run["bag"]))
    stems = [m.stem for m in args.model]
    results: dict[str, dict[str, float]] = {}
    for name, bags in sorted(bags_of.items()):
        car, work = fleet[name], args.out / name
        work.mkdir(parents=True, exist_ok=True)
        desc = work / "description.yaml"
        desc.write_text(yaml.safe_dump(description(car), sort_keys=False))
        described = work / "described.ukf.yaml"
        described.write_text(Description.load(desc).ukf_params_yaml())
        true_file = write_true_ukf(car, work / "true.ukf.yaml", "described_validation.py")
        mae: dict[str, float] = {}
        identified = None
        if "identified" in tags:
            identified = args.identified / name / "identified-5min.ukf.yaml"
            if not identified.exists():
                print(f"{name}: no {identified}", file=sys.stderr)
                return 2
        for tag, files in (
            ("described", observer_file_args(desc, described)),
            ("true", ["--ukf-params", str(true_file)]),
            *([] if identified is None else [("identified", observer_file_args(desc, identified))]),
        ):
            if tag not in tags:
                continue
            report = work / f"report-{tag}"
            code = evaluate_main(["--model", *map(str, args.model), "--data", *bags,
                                  "--out", str(report), "--force", *files])  # fmt: skip
            if code:
                return code
            got = pooled_mae(report, stems, lone=stems[0] if len(stems) == 1 else None)
            mae.update({f"{k} [{tag}]": v for k, v in got.items()})
        results[name] = mae
        print(name, {k: round(v, 4) for k, v in mae.items() if "β" not in k}, file=sys.stderr)
    (args.out / "summary.json").write_text(json.dumps(results, indent=2) + "\n")
    for tag in tags:
        for key in [*stems, "UKF"]:
            values = [r[f"{key} [{tag}]"] for r in results.values()]
            mean = sum(values) / len(values)
            print(f"{tag:9s} {key:30s} mean over {len(values)} cars {mean:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
