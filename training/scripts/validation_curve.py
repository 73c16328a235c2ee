"""The learning curve's 5-minute recipe on validation cars, to choose fine-tuning options
before the held-out cars score them (issue 9; docs/evaluation/held-out-curve).

Per validation car (``fit_bags_check.py``'s fleet and own-driving seeds): MINUTES of its
own fleet-style driving, its description (``held_out_fit.description``) and the axles
``sideslip-identify-axles`` makes from that driving, as a user's path has them. Each
``--arm NAME=OPTIONS`` is one ``sideslip-train`` run on that driving; every arm shares
the base recipe (``--init START --profile quick --stride 10 --interpolate 0.25
--learning-rate 3e-4``, the car files, ``--seed``) and adds its OPTIONS (an arm's own
``--stride`` or ``--mirror`` win, being later). All arms and START are scored by
``sideslip-evaluate``'s default (as the node runs them) on the car's 18 benchmark-style
validation drives (``validation_benchmark.py``) with the same car files; pooled MAE
[deg] per car in ``OUT/results.json``, a markdown table on stdout.

    python training/scripts/validation_curve.py --cars 0 1 2 3 --drives data/val-benchmark \
        --arm "no=--mirror no" --arm "yes=--mirror yes" --out data/val-curve
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import yaml

from sideslip_sim.fleet import sample_fleet
from sideslip_sim.held_out import held_out_digests
from sideslip_sim.vehicle import VehicleParams
from sideslip_training.cli import train_main
from sideslip_training.evaluate_cli import main as evaluate_main
from sideslip_training.identify_axles import main as identify_main
from sideslip_training.init_model import resolve

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_check import OWN_SEED, VAL_CARS, VAL_SEED
from held_out_curve import model_mae, write_own_minutes
from held_out_fit import description

BASE_RECIPE = ("--profile", "quick", "--device", "cpu", "--quiet", "--stride", "10",
               "--interpolate", "0.25", "--learning-rate", "3e-4")  # fmt: skip


def arm(text: str) -> tuple[str, list[str]]:
    """``NAME=OPTIONS`` → (NAME, OPTIONS split on blanks)."""
    name, sep, options = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"--arm wants NAME=OPTIONS, got {text!r}")
    return name, options.split()


def car_files(car: VehicleParams, work: Path, minutes: float, seed: int) -> tuple[Path, Path, Path]:
    """The car's own driving, description and identified axles (made once, then reused)."""
    own = work / f"own-{minutes:g}min"
    write_own_minutes(car, minutes, seed, own, "own driving")
    desc = work / "description.yaml"
    desc.write_text(yaml.safe_dump(description(car), sort_keys=False))
    ident = work / f"identified-{minutes:g}min.ukf.yaml"
    if not ident.exists():
        code = identify_main(["--vehicle", str(desc), "--data", str(own), "--out", str(ident)])
        if code:
            raise SystemExit(code)
    return own, desc, ident


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cars", type=int, nargs="+", required=True, help="validation car indices")
    p.add_argument("--drives", type=Path, default=Path("data/val-benchmark"))
    p.add_argument("--arm", type=arm, action="append", required=True, help="NAME=OPTIONS")
    p.add_argument("--minutes", type=float, default=5.0)
    p.add_argument("--seed", type=int, default=7, help="training seed")
    p.add_argument("--start", default="fleet_ukf_ensemble")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    names = [name for name, _ in args.arm]
    if len(set(names)) != len(names):
        p.error(f"--arm names must differ, got {names}")
    start = resolve(args.start, "--start")
    fleet = sample_fleet(VAL_CARS, VAL_SEED, exclude_digests=held_out_digests()).vehicles
    done = args.out / "results.json"
    for k in args.cars:
        car = fleet[k]
        drives = sorted(str(b) for b in args.drives.glob(f"{car.name}_mu*"))
        if len(drives) != 18:
            print(f"{car.name}: expected 18 drives under {args.drives}, got {len(drives)}")
            return 2
        work = args.out / car.name
        own, desc, ident = car_files(car, work, args.minutes, OWN_SEED + k)
        files = ["--vehicle", str(desc), "--observer-params", str(ident), "--car", "given"]
        models, seconds = {}, {}
        for name, options in args.arm:
            out = work / f"{name}-s{args.seed}.safetensors"
            if not out.exists():
                began = time.perf_counter()
                code = train_main(["--data", str(own), "--init", str(start), "--out", str(out),
                                   "--force", "--seed", str(args.seed), *BASE_RECIPE, *files,
                                   *options])  # fmt: skip
                if code:
                    return code
                seconds[name] = round(time.perf_counter() - began)
            models[name] = out
        report = work / f"report-s{args.seed}"
        code = evaluate_main(["--model", *(str(m) for m in models.values()), str(start),
                              "--data", *drives, "--out", str(report), "--force", *files,
                              "--ukf-params", str(ident)])  # fmt: skip
        if code:
            return code
        # Read again just before writing: another process may run other cars into OUT.
        results = json.loads(done.read_text()) if done.exists() else {}
        entry = results.setdefault(car.name, {}).setdefault(f"seed {args.seed}", {})
        for name, model in models.items():
            entry[name] = {"mae_deg": model_mae(report, model),
                           "options": dict(args.arm)[name],
                           **({"train_s": seconds[name]} if name in seconds else {})}  # fmt: skip
        entry["zero-shot"] = {"mae_deg": model_mae(report, start)}
        done.parent.mkdir(parents=True, exist_ok=True)
        done.write_text(json.dumps(results, indent=2) + "\n")
        print(f"{car.name} seed {args.seed}: {json.dumps(entry)}", file=sys.stderr)
    results = json.loads(done.read_text()) if done.exists() else {}
    columns = sorted({c for cars in results.values() for s in cars.values() for c in s})
    print("| car | seed | " + " | ".join(columns) + " |")
    print("|---|---|" + "---|" * len(columns))
    for car, seeds in sorted(results.items()):
        for seed, entry in sorted(seeds.items()):
            cells = [f"{entry[c]['mae_deg']:.4f}" if c in entry else "—" for c in columns]
            print(f"| {car} | {seed.split()[1]} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
