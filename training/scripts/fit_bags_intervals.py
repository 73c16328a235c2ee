"""Do a fitted model's 95 % intervals hold? ``sideslip-fit --bags`` models on the
validation-fleet cars of ``fit_bags_check.py``, scored on the card's test part (each own
recording's last 30 %) and on the car's four validation-fleet drives (new drives).

Per car, the share of samples with |β̂ − β| ≤ 1.96 σ for three σ on the same fitted
model's errors:

- ``calibrated``: what the model now carries (``sideslip-train --intervals auto``: the
  start model's σ terms, their scale fitted on the validation stretch with the model
  chosen before the refit);
- ``start's σ``: the start model's σ unchanged (terms and scale fitted on the fleet);
- ``constant``: the validation RMSE² that fitted models published before;

and, for reference, the shipped model zero-shot with its own σ (what the node gives
without the fit). Writes ``OUT`` (JSON) and prints a markdown table.

    python training/scripts/fit_bags_intervals.py --cars data/fit-bags-sigma/fleet2_car00{0..3} \
        data/fit-bags-sigma-b/fleet2_car00{4..7} --drives data/fleet-val --out FILE.json
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

from sideslip_msgs_py.uncertainty import Uncertainty
from sideslip_training.calibrate import Errors
from sideslip_training.dataset import load_runs
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve
from sideslip_training.splits import split_in_time

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_folder import fitted_car, study_parser

START = "fleet_ukf_measurable"
TEST_FRACTION = 0.3
WHERE = ("test part", "new drives")


def inside(errors: Errors, unc: Uncertainty) -> tuple[float, list[float]]:
    """Pooled share inside ±1.96 σ, and per run."""
    ok = np.abs(errors.err) <= 1.959963984540054 * np.sqrt(errors.variance(unc))
    return float(ok.mean()), [float(ok[errors.run == i].mean()) for i in np.unique(errors.run)]


def main(argv: list[str] | None = None) -> int:
    p = study_parser(__doc__)
    args = p.parse_args(argv)
    start_net, start_meta = load_model(resolve(START))
    start_unc = Uncertainty.from_dict(start_meta.uncertainty)
    summary: dict[str, dict] = {}
    for work in args.cars:
        fitted = work / "fitted.safetensors"
        net, meta = load_model(fitted)
        train = json.loads((work / "fitted.fit" / "train-run" / "metrics.json").read_text())
        constant = Uncertainty((1.0, 0.0, 0.0, 0.0), math.radians(train["val_rmse_deg"]))
        car = fitted_car(work)
        own, _ = load_runs([work / "own"], step_s=meta.dt_s)
        _, tail = split_in_time(own, TEST_FRACTION, "test")
        tail = [r for r in tail if len(r.samples) >= meta.window_steps]
        drives, _ = load_runs(sorted(args.drives.glob(f"{work.name}_*")), step_s=meta.dt_s)
        row: dict[str, dict] = {}
        for where, runs in zip(WHERE, (tail, drives), strict=True):
            mine = Errors.of_runs(runs, net, meta, **car)
            shipped = Errors.of_runs(runs, start_net, start_meta, **car)
            sigmas = {
                "calibrated": Uncertainty.from_dict(meta.uncertainty) if meta.uncertainty else None,
                "start's σ": start_unc,
                "constant": constant,
            }
            row[where] = {
                name: {"pooled": c[0], "runs": c[1]}
                for name, unc in sigmas.items()
                if unc is not None
                for c in [inside(mine, unc)]
            }
            pooled, per_run = inside(shipped, start_unc)
            row[where]["shipped zero-shot"] = {"pooled": pooled, "runs": per_run}
        row["scale"] = {
            "calibrated": (meta.uncertainty or {}).get("scale"),
            "start": start_unc.scale,
            "constant_deg": train["val_rmse_deg"],
        }
        summary[work.name] = row
        brief = {w: {k: round(v["pooled"], 3) for k, v in row[w].items()} for w in WHERE}
        print(work.name, json.dumps(brief), flush=True)
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    names = ["calibrated", "start's σ", "constant", "shipped zero-shot"]
    print("| car | where | " + " | ".join(names) + " |")
    print("|---|---|" + "---|" * len(names))
    for car_name, row in summary.items():
        for where in WHERE:
            cells = [f"{row[where][n]['pooled']:.3f}" if n in row[where] else "—" for n in names]
            print(f"| {car_name} | {where} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
