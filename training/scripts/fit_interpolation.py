"""A fitted model's weights moved back toward its start model's: θ = θ₀ + α (θ_fit − θ₀),
scored on the car's other drives, for ``fit_bags_check.py`` folders.

Fine-tuning from a better start model (O5U) gained on the recordings' own test part but
lost on the cars' other drives (docs/evaluation/fit-bags, "The retrained start model").
Interpolating in weight space between the start and the fine-tuned weights (weight-space
ensembling, "WiSE-FT", Wortsman et al., CVPR 2022) keeps part of what the start knew
about other driving; α = 0 is the start model with the car's identified file, α = 1 the
fit as ``sideslip-fit`` wrote it. Both networks share one normalisation (``sideslip-fit``
keeps the start's), which this checks, so the weights are comparable.

Per car, on its other drives (``--drives``): pooled MAE [deg] for every α, the files the
node would be given (description, identified axles, ``--car given``), the fitted model's
own estimate beyond its range (``beyond_fit_range model``). Writes ``OUT`` (JSON),
prints a markdown table.

    python training/scripts/fit_interpolation.py --cars data/fit-bags-check-u/fleet2_car00{0,1} \
        --drives data/val-benchmark --out FILE.json

Fits from a description (``fit_validation.py`` folders: ``--fitted fit-STEM``, the
described car's file beside it) from another start (``--start``):

    python training/scripts/fit_interpolation.py --cars data/fit-validation/fleet2_car0* \
        --fitted fit-o5dm --start O5DM.safetensors --drives data/val-benchmark --out FILE.json
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import torch

from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import evaluate_runs, pooled
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve
from sideslip_training.model import SideslipNet

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_folder import fitted_car, study_parser

START = "fleet_ukf_measurable"
NORMALISATION = ("features", "feature_mean", "feature_std", "beta_mean", "beta_std", "prior")


def interpolated(start: SideslipNet, fitted: SideslipNet, alpha: float) -> SideslipNet:
    """A copy of ``fitted`` with weights θ₀ + α (θ_fit − θ₀)."""
    s0, s1 = start.state_dict(), fitted.state_dict()
    net = SideslipNet(fitted.config)
    net.load_state_dict({k: s0[k] + alpha * (s1[k] - s0[k]) for k in s1}, strict=True)
    return net.eval()


def main(argv: list[str] | None = None) -> int:
    p = study_parser(__doc__)
    p.add_argument("--drive-glob", default="{car}_*", help="the car's drives in --drives")
    p.add_argument("--alphas", type=float, nargs="+", default=[0.0, 0.25, 0.5, 0.75, 1.0])
    p.add_argument("--start", default=START, help="the start model the fits fine-tuned")
    p.add_argument("--fitted", default="fitted", help="the fitted model's file stem")
    args = p.parse_args(argv)
    start_net, start_meta = load_model(resolve(args.start))
    summary: dict[str, dict[str, float]] = {}
    torch.set_num_threads(1)
    for work in args.cars:
        net, meta = load_model(work / f"{args.fitted}.safetensors")
        for key in NORMALISATION:
            if np.any(np.asarray(getattr(meta, key)) != np.asarray(getattr(start_meta, key))):
                raise SystemExit(f"{work}: {key} differs from {args.start}'s: not comparable")
        drives = sorted(args.drives.glob(args.drive_glob.format(car=work.name)))
        if not drives:
            raise SystemExit(f"{work.name}: no drives in {args.drives}")
        runs, _ = load_runs(drives, step_s=meta.dt_s)
        models = [(f"a{a:g}", interpolated(start_net, net, a), meta) for a in args.alphas]
        traces = evaluate_runs(
            runs,
            models,
            window_steps=meta.window_steps,
            dt_s=meta.dt_s,
            beyond_fit_range="model",
            **fitted_car(work, args.fitted),
        )
        rows = pooled(traces)
        summary[work.name] = {name: rows[name].mae for name, _, _ in models}
        print(work.name, json.dumps({k: round(v, 4) for k, v in summary[work.name].items()}))
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    names = [f"a{a:g}" for a in args.alphas]
    print("| car | " + " | ".join(f"α = {a:g}" for a in args.alphas) + " |")
    print("|---|" + "---|" * len(names))
    for car, row in summary.items():
        print(f"| {car} | " + " | ".join(f"{row[n]:.4f}" for n in names) + " |")
    means = [float(np.mean([row[n] for row in summary.values()])) for n in names]
    print("| mean | " + " | ".join(f"{m:.4f}" for m in means) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
