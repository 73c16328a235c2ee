"""``sideslip-fit --features measurable`` from each validation car's description, from
several start models: the choice of the fit's start for owners who have only a
description, made on validation cars, never on the held-out ones.

For each car of ``validation_benchmark.py`` folders (fleet-val cars driven the held-out
way, 18 runs per car), its description (``held_out_fit.description``) and every
``--init`` model:

    sideslip-fit --vehicle DESC --features measurable --init START --out CAR/fit-START.safetensors

(the quick profile, the cars' simulated data shared by the starts). Then the fitted
models and their starts zero-shot are scored on the car's 18 runs with the described
car's ``ukf`` file, as the node would run them (``sideslip-evaluate``, pooled MAE).
Cars run in ``--jobs`` worker processes, one torch thread each.

    python training/scripts/fit_validation.py --init fleet_ukf_measurable o5dm.safetensors \\
        --data data/val-benchmark data/val-benchmark-2 --out data/fit-validation --jobs 2

``--fit-only`` stops after the fits (their files can then be scored elsewhere with the
same command: finished fits are kept, not redone); with ``--cars`` it needs no
``--data``. ``--held-out`` takes the cars from ``sideslip_sim.held_out`` instead: a fit
reads only the description and its own simulated fleet, so fitting held-out cars looks
at nothing of the held-out benchmark; scoring them (``--data data/held-out``) is for a
start chosen before, once.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import sys
import time
from collections import defaultdict
from concurrent import futures
from pathlib import Path
from typing import Any

import yaml

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_check import VAL_CARS, VAL_SEED
from held_out_fit import description, observer_file_args, pooled_mae


def start_stem(spec: str) -> str:
    """The file stem ``sideslip-evaluate`` labels a start model with."""
    from sideslip_training.init_model import resolve

    return resolve(spec).stem


def cars(held_out: bool) -> dict[str, Any]:
    """The validation fleet's cars (or the held-out ones) by name."""
    from sideslip_sim.fleet import sample_fleet
    from sideslip_sim.held_out import held_out_digests, held_out_vehicles

    if held_out:
        return held_out_vehicles()
    fleet = sample_fleet(VAL_CARS, VAL_SEED, exclude_digests=held_out_digests())
    return {v.name: v for v in fleet.vehicles}


def fit_one_car(
    name: str,
    bags: list[str],
    starts: list[str],
    work: Path,
    device: str,
    fit_only: bool,
    fit_args: list[str],
    held_out: bool,
) -> dict[str, float]:
    """The car's fits from every start, then (unless ``fit_only``) the pooled MAE [deg]
    of each fit and each start with the described car's files."""
    import torch

    torch.set_num_threads(1)
    from sideslip_training.evaluate_cli import main as evaluate_main
    from sideslip_training.fit import Description
    from sideslip_training.fit import main as fit_main
    from sideslip_training.init_model import resolve

    work.mkdir(parents=True, exist_ok=True)
    desc = work / "description.yaml"
    desc.write_text(yaml.safe_dump(description(cars(held_out)[name]), sort_keys=False))
    fits = []
    for start in starts:
        fit = work / f"fit-{start_stem(start)}.safetensors"
        fits.append(fit)
        if fit.exists():
            continue
        code = fit_main(["--vehicle", str(desc), "--out", str(fit), "--features", "measurable",
                         "--work", str(work / "fit-data"), "--init", start, "--profile", "quick",
                         "--device", device, "--jobs", "1", "--quiet", *fit_args])  # fmt: skip
        if code:
            raise RuntimeError(f"{name}: sideslip-fit --init {start} exited {code}")
    if fit_only:
        return {}
    described = work / "described.ukf.yaml"
    described.write_text(Description.load(desc).ukf_params_yaml())
    report = work / "report"
    models = [*map(str, fits), *(str(resolve(s)) for s in starts)]
    code = evaluate_main(["--model", *models, "--data", *bags, "--out", str(report), "--force",
                          "--title", f"{name}: fits from each start, described car files",
                          *observer_file_args(desc, described)])  # fmt: skip
    if code:
        raise RuntimeError(f"{name}: sideslip-evaluate exited {code}")
    return pooled_mae(report, [*(f.stem for f in fits), *(start_stem(s) for s in starts)])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--init", nargs="+", required=True, help="start models (names or files)")
    p.add_argument("--data", nargs="+", type=Path, default=[], help="benchmark-style runs")
    p.add_argument("--held-out", action="store_true", help="the held-out cars")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--cars", nargs="*", help="car names (default: every car in --data)")
    p.add_argument("--jobs", type=int, default=2, help="cars fitted at once")
    p.add_argument("--device", default="cpu", choices=["auto", "cpu", "cuda"])
    p.add_argument("--fit-only", action="store_true", help="fit, do not score")
    p.add_argument(
        "--fit-args", default="", help='more sideslip-fit options, e.g. "--cars 2 --max-epochs 1"'
    )
    args = p.parse_args(argv)
    stems = [start_stem(s) for s in args.init]
    if len(set(stems)) != len(stems):
        p.error(f"--init: two start models share a file stem: {stems}")
    bags_of: dict[str, list[str]] = defaultdict(list)
    for folder in args.data:
        for run in json.loads((folder / "index.json").read_text())["runs"]:
            bags_of[run["vehicle"]].append(str(folder / run["bag"]))
    names = args.cars or sorted(bags_of)
    if not names:
        p.error("no cars: give --data (or, with --fit-only, --cars)")
    known = cars(args.held_out)
    unknown = [n for n in names if n not in known or not (args.fit_only or n in bags_of)]
    if unknown:
        p.error(f"--cars {unknown}: not a car of this fleet, or no runs of it in --data")
    os.environ["OMP_NUM_THREADS"] = "1"
    results: dict[str, dict[str, float]] = {}
    failed: list[str] = []
    started = time.perf_counter()
    ctx = multiprocessing.get_context("spawn")
    with futures.ProcessPoolExecutor(max_workers=args.jobs, mp_context=ctx) as pool:
        pending = {
            pool.submit(fit_one_car, n, bags_of[n], args.init, args.out / n, args.device,
                        args.fit_only, args.fit_args.split(), args.held_out): n
            for n in names
        }  # fmt: skip
        for fut in futures.as_completed(pending):
            name, at = pending[fut], time.perf_counter() - started
            try:
                results[name] = fut.result()
            except Exception as err:  # one car's failure must not lose the others
                failed.append(name)
                print(f"{name}: failed after {at:.0f} s: {err}", file=sys.stderr, flush=True)
                continue
            print(f"{name} done at {at:.0f} s:",
                  {k: round(v, 4) for k, v in results[name].items() if "β" not in k},
                  file=sys.stderr, flush=True)  # fmt: skip
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    if args.fit_only:
        return 0
    results = dict(sorted(results.items()))
    (args.out / "summary.json").write_text(json.dumps(results, indent=2) + "\n")
    keys = [*(f"fit-{s}" for s in stems), *stems, "UKF"]
    lines = ["| car | " + " | ".join(keys) + " |", "|---" * (len(keys) + 1) + "|"]
    for name, mae in results.items():
        lines.append(f"| {name} | " + " | ".join(f"{mae[k]:.4f}" for k in keys) + " |")
    means = {k: sum(r[k] for r in results.values()) / len(results) for k in keys}
    lines.append("| mean | " + " | ".join(f"{means[k]:.4f}" for k in keys) + " |\n")
    best = {n: min(keys[: len(stems)], key=lambda k: r[k]) for n, r in results.items()}
    for k in keys[: len(stems)] if len(stems) > 1 else []:
        lines.append(f"{k}: best fit on {sum(b == k for b in best.values())} of {len(best)} cars")
    (args.out / "table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
