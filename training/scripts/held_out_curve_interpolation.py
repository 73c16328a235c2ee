"""Other shares of ``--interpolate`` for fine-tunings ``held_out_curve.py`` already made,
scored on the held-out car's 18 benchmark runs, without training again.

``sideslip-train --interpolate α`` writes θ₀ + α (θ_ft − θ₀) (θ₀ the ``--init`` start,
θ_ft the best epoch's weights; the epoch is chosen before the interpolation). The model
written with α_w therefore gives any α ≤ α_w, as θ₀ + (α / α_w)(θ_w − θ₀) (exact
but for float32 rounding, ~1e-7);
a training that kept the start (best epoch 0) is the start at every α. Used for the
share chosen on validation cars after the held-out six had been scored with another
(``fit_interpolation.py`` chose it; this only scores it).

Per work folder (``CAR-measurable-TAG``): the car's description and identified file from
``--identified DIR/CAR`` (``held_out_fit.py --identify``), the car's runs
``CAR_mu*`` in ``--held-out``, pooled MAE [deg] per α. Writes ``--out`` (JSON).

    python training/scripts/held_out_curve_interpolation.py --start fleet_ukf_merged \
        --work data/held-out-curve-m/*-s? --identified data/hofm-ident --alphas 0.25 \
        --out docs/evaluation/held-out-curve/user-path-5min-merged-alpha.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch

from sideslip_msgs_py.vehicle_description import VehicleDescription
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import evaluate_runs, pooled
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve

sys.path.insert(0, str(Path(__file__).parent))
from fit_interpolation import NORMALISATION, interpolated


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", type=Path, nargs="+", required=True, help="held_out_curve folders")
    p.add_argument("--start", required=True, help="the --init the fine-tunings started from")
    p.add_argument("--identified", type=Path, required=True, help="folder of CAR/ car files")
    p.add_argument("--held-out", type=Path, default=Path("data/held-out"))
    p.add_argument("--minutes", default="5", help="which amount's model (finetuned_Nmin)")
    p.add_argument("--alphas", type=float, nargs="+", required=True, help="shares to score")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    start_net, start_meta = load_model(resolve(args.start, "--start"))
    torch.set_num_threads(1)
    summary: dict[str, dict[str, float]] = {}
    for work in args.work:
        car = work.name.split("-measurable")[0]
        model = work / f"finetuned_{args.minutes}min.safetensors"
        net, meta = load_model(model)
        for key in NORMALISATION:
            if np.any(np.asarray(getattr(meta, key)) != np.asarray(getattr(start_meta, key))):
                raise SystemExit(f"{model}: {key} differs from {args.start}'s: not comparable")
        run = json.loads((work / f"finetuned_{args.minutes}min.run" / "metrics.json").read_text())
        kept = run["best_epoch"] == 0
        written = 1.0 if kept else float(run.get("interpolate", 1.0))
        if not kept and max(args.alphas) > written:
            raise SystemExit(f"{model}: written with α {written:g}; only α ≤ {written:g} here")
        models = [
            (f"a{a:g}", start_net if kept else interpolated(start_net, net, a / written), meta)
            for a in args.alphas
        ]
        files = args.identified / car
        bags = sorted(args.held_out.glob(f"{car}_mu*"))
        runs, _ = load_runs(bags, step_s=meta.dt_s)
        traces = evaluate_runs(
            runs,
            models,
            window_steps=meta.window_steps,
            dt_s=meta.dt_s,
            vehicle=VehicleDescription.load(files / "description.yaml"),
            observer_params_file=str(files / f"identified-{args.minutes}min.ukf.yaml"),
            car="given",
        )
        rows = pooled(traces)
        summary[work.name] = {
            "written_alpha": written,
            "start_kept": kept,
            **{name: rows[name].mae for name, _, _ in models},
        }
        print(work.name, json.dumps(summary[work.name]))
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
