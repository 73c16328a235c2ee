"""What a residual model's error is made of, per run: its bias, its slow part, and the
share a per-run gain on β and offset explain, beside the same for its own prior (for a
residual on the UKF, that filter). Validation folders only (docs/evaluation/scenario-driving).

    python training/scripts/error_structure.py --model fleet_ukf_ensemble_disturbance \\
        --data data/val-benchmark --out error-structure.json
"""

from __future__ import annotations

import argparse
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

SLOW_S = 1.0  # the slow part: a centred moving average over this long [s]


def run_row(e: np.ndarray, beta: np.ndarray, dt_s: float) -> dict[str, float]:
    """Error figures [deg] of one run's error ``e`` against its reference ``beta`` [deg]."""
    n = max(1, round(SLOW_S / dt_s))
    x = np.c_[beta, np.ones_like(beta)]
    coef, *_ = np.linalg.lstsq(x, e, rcond=None)
    return {
        "mae": float(np.abs(e).mean()),
        "bias": float(e.mean()),
        "mae_without_bias": float(np.abs(e - e.mean()).mean()),
        "mae_of_slow_part": float(np.abs(np.convolve(e, np.ones(n) / n, "same")).mean()),
        "gain": float(coef[0]),
        "mae_without_gain_and_offset": float(np.abs(e - x @ coef).mean()),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", required=True, help="a shipped name or .safetensors (with a prior)")
    p.add_argument("--data", nargs="+", required=True, help="folders with index.json")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    net, meta = load_model(resolve(args.model))
    if meta.prior == "none":
        p.error(f"{args.model}: has no prior to compare its error with")
    w = meta.window_steps
    index = {
        r["bag"]: r
        for f in args.data
        for r in json.loads((Path(f) / "index.json").read_text())["runs"]
    }
    runs, _ = load_runs(args.data, step_s=meta.dt_s)
    spec = InputSpec(meta.features, meta.prior, meta.dt_s, None, meta.observer)
    rows = []
    for run in runs:
        beta = run.samples.beta_rad()[w - 1 :]
        est = predict_run(net, meta, run, mirror_average="auto")
        prior = spec.prior_rad(run, w)[w - 1 :]
        ok = np.isfinite(est) & np.isfinite(prior)
        b = np.degrees(beta[ok])
        e, ep = np.degrees(est[ok]) - b, np.degrees(prior[ok]) - b
        entry = index[Path(str(run.bag)).name]
        rows.append(
            {
                "bag": entry["bag"],
                "vehicle": entry["vehicle"],
                "family": entry["family"],
                "mu": float(entry["mu"]),
                "model": run_row(e, b, meta.dt_s),
                "prior": run_row(ep, b, meta.dt_s),
                "correlation": float(np.corrcoef(e, ep)[0, 1]),
            }
        )
    summary: dict[str, dict] = {}
    groups: dict[str, list[dict]] = defaultdict(list)
    for r in rows:
        groups["all"].append(r)
        groups[r["family"]].append(r)
    for name, rs in groups.items():
        summary[name] = {
            "runs": len(rs),
            **{
                f"{who}_{k}": float(
                    np.mean([abs(r[who][k]) if k in ("bias", "gain") else r[who][k] for r in rs])
                )
                for who in ("model", "prior")
                for k in rows[0]["model"]
            },
            "correlation": float(np.mean([r["correlation"] for r in rs])),
        }
        s = summary[name]
        print(
            f"{name:12s} runs {len(rs):3d}  model MAE {s['model_mae']:.4f}"
            f" (|bias| {s['model_bias']:.4f},"
            f" slow {s['model_mae_of_slow_part']:.4f}, without gain+offset "
            f"{s['model_mae_without_gain_and_offset']:.4f})  prior MAE {s['prior_mae']:.4f}"
            f" (|bias| {s['prior_bias']:.4f})  correlation {s['correlation']:.2f}"
        )
    args.out.write_text(json.dumps({"model": args.model, "data": args.data, "slow_s": SLOW_S,
                                    "summary": summary, "runs": rows}, indent=1))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
