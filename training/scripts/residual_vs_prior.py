"""A residual model against its own prior, on the same samples, per car and per car × μ.

Issue 8 asks the ``measurable`` model to beat the best physics filter by 2× on every
car. For a residual on the UKF (``--prior ukf``) the filter it corrects is its prior,
run with the settings stored in the model: here the model's β̂ and that prior are scored
on exactly the same samples (those where both are finite, after the first full window),
so the ratio says what the network adds. Meant for validation bags (fleet-val,
``validation_benchmark.py`` folders), to choose before anything is scored on the
held-out cars. Each bag is read with its own recorded car (true nominal parameters).

    python training/scripts/residual_vs_prior.py --model fleet_ukf_measurable new.safetensors \
        --data data/val-benchmark data/val-benchmark-2 --out residual-vs-prior.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from sideslip_training import observer
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve
from sideslip_training.inputs import InputSpec


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", nargs="+", required=True, help="shipped names or .safetensors")
    p.add_argument("--data", nargs="+", required=True, help="folders of bags with index.json")
    p.add_argument("--jobs", type=int, default=1, help="processes for the UKF observer")
    p.add_argument("--out", type=Path)
    args = p.parse_args(argv)

    models: dict[str, object] = {}
    for spec_name in args.model:
        net, meta = load_model(resolve(spec_name))
        if meta.prior == "none":
            raise SystemExit(f"{spec_name}: no prior to compare with")
        spec = InputSpec(meta.features, meta.prior, meta.dt_s, None, meta.observer, None)
        w = meta.window_steps
        errors: dict[tuple[str, float], list[tuple[np.ndarray, np.ndarray]]] = {}
        for folder in args.data:
            index = {
                r["bag"]: r for r in json.loads((Path(folder) / "index.json").read_text())["runs"]
            }
            runs, _ = load_runs([folder], step_s=meta.dt_s)
            if spec.needs_observer:
                assert meta.observer is not None
                observer.precompute(runs, meta.observer, None, jobs=args.jobs, progress=False)
            for run in runs:
                entry = index[Path(str(run.bag)).name]
                ref = run.samples.beta_rad()[w - 1 :]
                est = predict_run(net, meta, run)
                prior = spec.prior_rad(run, w)[w - 1 :]
                ok = np.isfinite(est) & np.isfinite(prior) & np.isfinite(ref)
                key = (str(entry["vehicle"]), float(entry.get("mu", float("nan"))))
                errors.setdefault(key, []).append(
                    (np.degrees(np.abs(est - ref)[ok]), np.degrees(np.abs(prior - ref)[ok]))
                )

        def row(pairs: list[tuple[np.ndarray, np.ndarray]]) -> dict[str, float]:
            net_err = np.concatenate([a for a, _ in pairs])
            prior_err = np.concatenate([b for _, b in pairs])
            return {
                "samples": int(net_err.size),
                "model_mae_deg": float(net_err.mean()),
                "prior_mae_deg": float(prior_err.mean()),
                "ratio": float(net_err.mean() / prior_err.mean()),
            }

        cars = sorted({car for car, _ in errors})
        per_car = {c: row([x for (k, _), v in errors.items() if k == c for x in v]) for c in cars}
        per_cell = {f"{c} mu={mu:g}": row(v) for (c, mu), v in sorted(errors.items())}
        pooled = row([x for v in errors.values() for x in v])
        ratios = [r["ratio"] for r in per_car.values()]
        summary = {
            "pooled": pooled,
            "cars": len(cars),
            "cars_better_than_prior": sum(r < 1.0 for r in ratios),
            "cars_at_most_half": sum(r <= 0.5 for r in ratios),
            "car_ratio_min_median_max": [
                float(np.min(ratios)),
                float(np.median(ratios)),
                float(np.max(ratios)),
            ],
        }
        models[spec_name] = {
            "prior": meta.prior,
            "summary": summary,
            "per_car": per_car,
            "per_cell": per_cell,
        }
        print(f"{spec_name} (prior {meta.prior}):")
        print(
            f"  pooled MAE {pooled['model_mae_deg']:.4f} vs prior {pooled['prior_mae_deg']:.4f} "
            f"(ratio {pooled['ratio']:.2f}); cars better than the prior "
            f"{summary['cars_better_than_prior']}/{len(cars)}, at most 0.5x "
            f"{summary['cars_at_most_half']}/{len(cars)}; per-car ratio min/median/max "
            + " / ".join(f"{r:.2f}" for r in summary["car_ratio_min_median_max"])
        )
    if args.out is not None:
        args.out.write_text(json.dumps({"data": args.data, "models": models}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
