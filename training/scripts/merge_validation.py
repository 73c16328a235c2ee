"""Measurable models against the UKF they are a residual on, per validation car: the choice
of ``sideslip-merge``'s members, made without the held-out cars.

On ``validation_benchmark.py`` folders (fleet-val cars driven the held-out way, each
bag's true car), every ``--model`` and the UKF prior of the first one are scored on the
same samples (where every estimate is finite); per car the pooled MAE [deg] and its ratio
to the UKF's (issue 8 asks ≤ 0.5 on every car), and pooled over all cars. ``--pairs``
adds the mean of every two models' β̂ (what ``sideslip-merge`` of that pair gives),
``--subsets`` the mean of every two or more. ``--cache DIR`` keeps each model's β̂ per run
(keyed by the model file's SHA-256), so a new member is scored against the old ones
without running them again.

For single models (one row each, per car × μ too) ``residual_vs_prior.py`` is the tool;
this script exists for ``--pairs``, which needs every model's β̂ of a run at once.

    python training/scripts/merge_validation.py --model fleet_ukf_measurable \
        fleet_ukf_described --pairs --data data/val-benchmark data/val-benchmark-2 \
        --out docs/models/fleet_ukf_merged/merge-validation.json
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve
from sideslip_training.inputs import InputSpec


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", nargs="+", required=True, help=".safetensors files or names")
    p.add_argument("--data", nargs="+", required=True, help="validation_benchmark.py folders")
    p.add_argument("--pairs", action="store_true", help="also the mean of every two models")
    p.add_argument(
        "--subsets", action="store_true", help="also the mean of every two or more models"
    )
    p.add_argument(
        "--cache",
        type=Path,
        help="folder for each model's estimates per run, reused when the model file is the same",
    )
    p.add_argument("--out", type=Path, required=True, help="JSON report")
    args = p.parse_args(argv)
    nets = {name: load_model(resolve(name)) for name in args.model}
    cache = args.cache
    files = {name: _cache_file(cache, resolve(name)) for name in args.model} if cache else {}
    cached = {name: _cached(path) for name, path in files.items()}
    added: set[str] = set()
    first = next(iter(nets.values()))[1]
    if first.prior != "ukf":
        print(f"{args.model[0]}: not a residual on the UKF (prior {first.prior})")
        return 2
    runs, _ = load_runs(args.data, step_s=first.dt_s)
    index = {
        r["bag"]: r
        for folder in args.data
        for r in json.loads((Path(folder) / "index.json").read_text())["runs"]
    }
    spec = InputSpec(first.features, first.prior, first.dt_s, None, first.observer)
    w = first.window_steps
    errors: dict[str, dict[str, list[np.ndarray]]] = defaultdict(lambda: defaultdict(list))
    for run in runs:
        ref = run.samples.beta_rad()[w - 1 :]
        bag = Path(str(run.bag)).name
        est = {}
        for name, (net, meta) in nets.items():
            store = cached.get(name)
            if store is not None and bag in store:
                est[name] = store[bag]
            else:
                est[name] = predict_run(net, meta, run)
                if store is not None:
                    store[bag] = est[name]
                    added.add(name)
        sizes = range(2, len(args.model) + 1) if args.subsets else [2] if args.pairs else []
        for k in sizes:
            for group in itertools.combinations(args.model, k):
                est[f"mean({', '.join(group)})"] = np.mean([est[g] for g in group], axis=0)
        est["UKF"] = spec.prior_rad(run, w)[w - 1 :]
        ok = np.isfinite(ref) & np.all([np.isfinite(e) for e in est.values()], axis=0)
        car = index[bag]["vehicle"]
        for name, e in est.items():
            errors[car][name].append(np.abs(e[ok] - ref[ok]))
    for name in added:
        np.savez(files[name], **cached[name])
    names, per_car, pooled = mae_per_car_and_pooled(errors)
    ratios = {n: [c[n] / c["UKF"] for c in per_car.values()] for n in names if n != "UKF"}
    summary = {
        n: {
            "pooled_mae_deg": pooled[n],
            "ratio_to_ukf_mean": float(np.mean(r)),
            "ratio_to_ukf_worst": float(np.max(r)),
            "cars_at_most_half_the_ukf": int(np.sum(np.asarray(r) <= 0.5)),
        }
        for n, r in ratios.items()
    }
    report = {
        "data": args.data,
        "cars": len(per_car),
        "ukf_pooled_mae_deg": pooled["UKF"],
        "summary": summary,
        "per_car_mae_deg": per_car,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=2) + "\n")
    print(f"UKF: pooled {pooled['UKF']:.4f} deg over {len(per_car)} cars")
    for n, s in summary.items():
        print(
            f"{n}: pooled {s['pooled_mae_deg']:.4f} deg, per car {s['ratio_to_ukf_mean']:.3f}x "
            f"the UKF (worst {s['ratio_to_ukf_worst']:.3f}x, "
            f"{s['cars_at_most_half_the_ukf']} cars <= 0.5x)"
        )
    return 0


def mae_per_car_and_pooled(
    errors: dict[str, dict[str, list[np.ndarray]]],
) -> tuple[list[str], dict[str, dict[str, float]], dict[str, float]]:
    """From absolute errors [rad] per car and estimator (a list of runs' arrays each): the
    estimators' names, their MAE [deg] per car and pooled over every sample."""
    names = list(next(iter(errors.values())))
    per_car = {
        car: {n: float(np.degrees(np.concatenate(e[n]).mean())) for n in names}
        for car, e in sorted(errors.items())
    }
    pooled = {
        n: float(np.degrees(np.concatenate([x for e in errors.values() for x in e[n]]).mean()))
        for n in names
    }
    return names, per_car, pooled


def _cache_file(folder: Path, model: Path) -> Path:
    """Where ``model``'s estimates are kept: keyed by the file's bytes, so a retrained
    model never reuses another's."""
    folder.mkdir(parents=True, exist_ok=True)
    return folder / f"{hashlib.sha256(model.read_bytes()).hexdigest()[:16]}.npz"


def _cached(path: Path) -> dict[str, np.ndarray]:
    """The estimates per bag name kept at ``path`` (empty when none yet)."""
    if not path.is_file():
        return {}
    with np.load(path) as kept:
        return {bag: kept[bag] for bag in kept.files}


if __name__ == "__main__":
    sys.exit(main())
