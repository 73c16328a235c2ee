"""Ways to hand a fitted model's estimate over to its start model beyond the
recordings' range, compared offline on ``fit_bags_check.py`` folders.

Per car, MAE [deg] on its drives (``--drives``) of:

* ``model``: the fitted model everywhere (``beyond_fit_range`` model);
* ``start``: the start model while the window reaches beyond the range (the node's
  ``auto`` today);
* ``blend``: the mean of the two while beyond;
* ``ramp K``: weight w on the start model, w = clip((d − 1) / K, 0, 1), where d is the
  window's largest ratio of |a_y| and |β̇| to the range (d ≤ 1: within): the further
  beyond, the more the start model;
* ``shipped``: the start model everywhere (zero-shot).

Writes ``OUT`` (JSON), prints a markdown table of the means and of how many cars each
way beats ``model`` on.

    python training/scripts/fit_range_handover.py --cars data/fit-bags-check-c/fleet2_car0{08..11} \
        --drives data/fleet-val --out FILE.json
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from sideslip_msgs_py.uncertainty import MIN_SPEED_MPS, Uncertainty
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_folder import fitted_car, study_parser
from fit_range_gate import START, with_fit_range

RAMPS = (0.25, 0.5, 1.0)


def depth(fit, s, w: int) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Per sample, the trailing window's largest ratio to the range (≤ 1: within)."""
    v = np.maximum(s.x_v_mps, MIN_SPEED_MPS)
    ratio = np.maximum(
        np.abs(s.y_a_mps2) / fit.lateral_acceleration_mps2,
        np.abs(s.y_a_mps2 / v - s.yaw_rate_radps) / fit.beta_rate_radps,
    )
    padded = np.concatenate([np.zeros(w - 1), ratio])
    return np.lib.stride_tricks.sliding_window_view(padded, w).max(axis=1)


def main(argv: list[str] | None = None) -> int:
    p = study_parser(__doc__)
    p.add_argument("--drive-glob", default="{car}_*", help="the car's drives in --drives")
    args = p.parse_args(argv)
    start_net, start_meta = load_model(resolve(START))
    summary: dict[str, dict[str, float]] = {}
    for work in args.cars:
        net, meta = load_model(work / "fitted.safetensors")
        meta = with_fit_range(work, meta, start_meta)
        fit = Uncertainty.from_dict(meta.uncertainty).fit_range
        car = fitted_car(work)
        drives = sorted(args.drives.glob(args.drive_glob.format(car=work.name)))
        runs, _ = load_runs(drives, step_s=meta.dt_s)
        w = meta.window_steps
        errors: dict[str, list[np.ndarray]] = {}
        for run in runs:
            f = predict_run(net, meta, run, **car)
            st = predict_run(start_net, start_meta, run, **car)
            ref = run.samples.beta_rad()[w - 1 :]
            d = depth(fit, run.samples, w)[w - 1 :]
            ok = np.isfinite(f) & np.isfinite(st) & np.isfinite(ref)
            ways = {
                "model": f,
                "start": np.where(d > 1.0, st, f),
                "blend": np.where(d > 1.0, 0.5 * (f + st), f),
                "shipped": st,
            }
            for k in RAMPS:
                weight = np.clip((d - 1.0) / k, 0.0, 1.0)
                ways[f"ramp {k:g}"] = (1.0 - weight) * f + weight * st
            for name, est in ways.items():
                errors.setdefault(name, []).append((est - ref)[ok])
        row = {k: float(np.degrees(np.abs(np.concatenate(e))).mean()) for k, e in errors.items()}
        summary[work.name] = row
        print(work.name, json.dumps({k: round(v, 4) for k, v in row.items()}), flush=True)
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    names = list(next(iter(summary.values())))
    print("| way | mean MAE [deg] | cars better than model / worse |")
    print("|---|---|---|")
    for name in names:
        mean = float(np.mean([m[name] for m in summary.values()]))
        better = sum(m[name] < m["model"] - 1e-6 for m in summary.values())
        worse = sum(m[name] > m["model"] + 1e-6 for m in summary.values())
        print(f"| {name} | {mean:.4f} | {better} / {worse} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
