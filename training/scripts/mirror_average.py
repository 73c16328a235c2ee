"""Does averaging a model with its own mirror image lower its error? Validation cars only.

A car is symmetric, so β of the run driven the other way round is exactly −β
(:mod:`sideslip_msgs_py.mirror`). A network trained on the fleet is symmetric only as
far as its training taught it; ``(f(x) − f(mirror x)) / 2`` is exactly odd and, where the
network's error has an even part, smaller. It costs a second pass per sample at run
time, so it is worth building into the node only if it pays on validation cars.

On ``validation_benchmark.py`` folders (each bag's true car), per car the pooled MAE
[deg] of the model, of its mirror average and of the UKF prior, and the ratios to the
UKF (issue 8 asks ≤ 0.5 on every car). ``--cache`` keeps each run's estimates, so the
summary is re-made without running the model again; ``--summary`` reads several caches.

    python training/scripts/mirror_average.py --model fleet_ukf_ensemble \
        --data data/val-benchmark --cache data/mirror/a.npz
    python training/scripts/mirror_average.py --summary data/mirror/a.npz data/mirror/b.npz \
        --out docs/models/fleet_ukf_ensemble/mirror-average-validation.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from sideslip_msgs_py.mirror import mirrored
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve
from sideslip_training.inputs import InputSpec

sys.path.insert(0, str(Path(__file__).parent))
from merge_validation import mae_per_car_and_pooled


def estimates(model: str, folders: list[str], cache: Path) -> None:
    """Writes, per run, the reference, the model's β̂, its β̂ on the mirrored run
    (negated back) and the UKF prior [rad] into ``cache``, keyed ``car|bag|kind``."""
    net, meta = load_model(resolve(model))
    runs, _ = load_runs(folders, step_s=meta.dt_s)
    index = {
        r["bag"]: r["vehicle"]
        for folder in folders
        for r in json.loads((Path(folder) / "index.json").read_text())["runs"]
    }
    spec = InputSpec(meta.features, meta.prior, meta.dt_s, None, meta.observer)
    w = meta.window_steps
    out: dict[str, np.ndarray] = {}
    for n, run in enumerate(runs, 1):
        bag = Path(str(run.bag)).name
        key = f"{index[bag]}|{bag}"
        flipped = dataclasses.replace(run, samples=mirrored(run.samples))
        out[f"{key}|ref"] = run.samples.beta_rad()[w - 1 :]
        out[f"{key}|model"] = predict_run(net, meta, run)
        out[f"{key}|mirror"] = -predict_run(net, meta, flipped)
        out[f"{key}|ukf"] = (
            spec.prior_rad(run, w)[w - 1 :]
            if meta.prior == "ukf"
            else np.full_like(out[f"{key}|ref"], np.nan)
        )
        print(f"{n}/{len(runs)} {bag}", file=sys.stderr, flush=True)
    cache.parent.mkdir(parents=True, exist_ok=True)
    np.savez(cache, **out)


def summary(caches: list[Path]) -> dict:
    """Per car and pooled MAE [deg] of the model, its mirror average and the UKF."""
    errors: dict[str, dict[str, list[np.ndarray]]] = defaultdict(lambda: defaultdict(list))
    for path in caches:
        with np.load(path) as kept:
            keys = sorted({k.rsplit("|", 1)[0] for k in kept.files})
            # A model without the UKF prior (fleet_lstm_paper) is scored without it.
            has_ukf = bool(np.isfinite(kept[f"{keys[0]}|ukf"]).any())
            for key in keys:
                car = key.split("|")[0]
                ref, model, mirror, ukf = (
                    kept[f"{key}|{k}"] for k in ("ref", "model", "mirror", "ukf")
                )
                est = {"model": model, "mirror average": (model + mirror) / 2, "mirrored": mirror}
                if has_ukf:
                    est["UKF"] = ukf
                ok = np.isfinite(ref) & np.all([np.isfinite(e) for e in est.values()], axis=0)
                for name, e in est.items():
                    errors[car][name].append(np.abs(e[ok] - ref[ok]))
    names, per_car, pooled = mae_per_car_and_pooled(errors)
    ratios = (
        {n: [c[n] / c["UKF"] for c in per_car.values()] for n in names if n != "UKF"}
        if "UKF" in names
        else {}
    )
    return {
        "cars": len(per_car),
        "pooled_mae_deg": pooled,
        # Both directions weigh alike: what a car that turns either way gets.
        "both_directions_mae_deg": {
            "model": (pooled["model"] + pooled["mirrored"]) / 2,
            "mirror average": pooled["mirror average"],
        },
        "ratio_to_ukf_mean": {n: float(np.mean(r)) for n, r in ratios.items()},
        "ratio_to_ukf_worst": {n: float(np.max(r)) for n, r in ratios.items()},
        "cars_mirror_average_better": int(
            sum(c["mirror average"] < c["model"] for c in per_car.values())
        ),
        "per_car_mae_deg": per_car,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", help=".safetensors file or shipped name")
    p.add_argument("--data", nargs="+", help="validation_benchmark.py folders")
    p.add_argument("--cache", type=Path, help="where this run's estimates go")
    p.add_argument("--summary", nargs="+", type=Path, help="caches to summarise")
    p.add_argument("--out", type=Path, help="JSON report (with --summary)")
    args = p.parse_args(argv)
    if args.summary:
        report = summary(args.summary)
        text = json.dumps(report, indent=2) + "\n"
        if args.out:
            args.out.parent.mkdir(parents=True, exist_ok=True)
            args.out.write_text(text)
        print(text)
        return 0
    if not (args.model and args.data and args.cache):
        p.error("--model, --data and --cache, or --summary")
    estimates(args.model, args.data, args.cache)
    return 0


if __name__ == "__main__":
    sys.exit(main())
