"""The node's ``beyond_fit_range``: a fitted model's estimate and σ against the start
model's beyond the recordings' range, through ``sideslip-evaluate``'s own path, for
``fit_bags_check.py`` folders.

Per car, on its other drives (``--drives``): MAE [deg] and the pooled share of samples
inside ±1.96 σ of the fitted model as it publishes with ``beyond_fit_range`` ``model``
(its own estimate, σ widened) and ``auto`` (the shipped start model's estimate and σ
while the window reaches beyond), and of the shipped model zero-shot. Writes ``OUT``
(JSON), prints a markdown table.

    python training/scripts/fit_range_gate.py --cars data/fit-bags-gentle/fleet2_car00{0..3} \
        data/fit-bags-gentle-b/fleet2_car00{4..7} --drives data/fleet-val --out FILE.json
"""

from __future__ import annotations

import dataclasses
import json
import re
import sys
from pathlib import Path

import numpy as np

from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import evaluate_runs, interval_coverage, pooled
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_folder import fitted_car, study_parser
from fit_range_forgetting import fit_range_of

from sideslip_msgs_py.uncertainty import Uncertainty
from sideslip_training.train_intervals import OUTSIDE_FACTOR

START = "fleet_ukf_measurable"
MU = re.compile(r"_mu(\d\d)_")
MODES = ("model", "auto")


def with_fit_range(work: Path, meta, start_meta):  # type: ignore[no-untyped-def]
    """``meta``, with the range ``sideslip-train`` records now when the model was fitted
    before it did (the same stretches: each own recording's first 70 %; ×2 the start's
    scale beyond)."""
    unc = Uncertainty.from_dict(meta.uncertainty)
    if unc.fit_range is not None:
        return meta
    fit = fit_range_of(work, meta)
    outside = OUTSIDE_FACTOR * Uncertainty.from_dict(start_meta.uncertainty).scale
    unc = dataclasses.replace(unc, fit_range=dataclasses.replace(fit, outside_scale=outside))
    return dataclasses.replace(meta, uncertainty=unc.to_dict())


def main(argv: list[str] | None = None) -> int:
    p = study_parser(__doc__)
    p.add_argument("--drive-glob", default="{car}_*", help="the car's drives in --drives")
    args = p.parse_args(argv)
    start = load_model(resolve(START))
    summary: dict[str, dict[str, float]] = {}
    for work in args.cars:
        net, meta = load_model(work / "fitted.safetensors")
        meta = with_fit_range(work, meta, start[1])
        car = fitted_car(work)
        drives = sorted(args.drives.glob(args.drive_glob.format(car=work.name)))
        runs, _ = load_runs(drives, step_s=meta.dt_s)
        row: dict[str, float] = {}
        for mode in MODES:
            traces = evaluate_runs(
                runs,
                [("fitted", net, meta), ("shipped", *start)],
                window_steps=meta.window_steps,
                dt_s=meta.dt_s,
                beyond_fit_range=mode,
                **car,
            )
            rows = pooled(traces)
            for name in ("fitted", "shipped"):
                mine = [t for t in traces if t.estimator == name]
                label = name if name == "shipped" else f"fitted ({mode})"
                row[label] = rows[name].mae
                row[f"{label} inside"] = interval_coverage(mine)
                # Held-out benchmark runs: per road (μ) cell as well.
                for mu in sorted({m.group(1) for t in mine if (m := MU.search(t.scenario))}):
                    cell = [t for t in mine if f"_mu{mu}_" in t.scenario]
                    row[f"{label} mu{mu}"] = pooled(cell)[name].mae
                    row[f"{label} mu{mu} inside"] = interval_coverage(cell)
        summary[work.name] = row
        print(work.name, json.dumps({k: round(v, 4) for k, v in row.items()}), flush=True)
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    print("| car | fitted, own beyond | fitted, start beyond (auto) | shipped | inside ±1.96 σ: "
          "own / start / shipped |")  # fmt: skip
    print("|---|---|---|---|---|")
    for name, m in summary.items():
        print(f"| {name} | {m['fitted (model)']:.4f} | {m['fitted (auto)']:.4f} | "
              f"{m['shipped']:.4f} | {m['fitted (model) inside']:.3f} / "
              f"{m['fitted (auto) inside']:.3f} / {m['shipped inside']:.3f} |")  # fmt: skip
    keys = ("fitted (model)", "fitted (auto)", "shipped")
    means = {k: float(np.mean([m[k] for m in summary.values()])) for k in keys}
    inside = {k: float(np.mean([m[f"{k} inside"] for m in summary.values()])) for k in keys}
    print(f"| mean | {means['fitted (model)']:.4f} | {means['fitted (auto)']:.4f} | "
          f"{means['shipped']:.4f} | {inside['fitted (model)']:.3f} / "
          f"{inside['fitted (auto)']:.3f} / {inside['shipped']:.3f} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
