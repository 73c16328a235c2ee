"""Does fine-tuning on gentle recordings forget the limit? Fitted against shipped on
the car's other drives, within and beyond the recordings' range, for
``fit_bags_check.py`` folders (validation cars).

Per car, MAE [deg] on its drives (``--drives``) of the fitted model, of the shipped
``fleet_ukf_measurable`` zero-shot (the fit's start) and of the two gated by the
recordings' range (the shipped model's β̂ while the input window reaches beyond
:class:`~sideslip_msgs_py.uncertainty.FitRange`, the fitted model's within): what a
node that falls back beyond the range would publish; and *blended*: the mean of the two
models' β̂ beyond the range, the fitted model's within. Writes ``OUT`` (JSON), prints a
markdown table.

    python training/scripts/fit_range_forgetting.py --cars data/fit-bags-gentle/fleet2_car00{0..3} \
        data/fit-bags-gentle-b/fleet2_car00{4..7} --drives data/fleet-val --out FILE.json
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from sideslip_msgs_py.uncertainty import FitRange, Uncertainty
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve
from sideslip_training.splits import split_in_time

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_folder import fitted_car, study_parser

START = "fleet_ukf_measurable"
TEST_FRACTION = 0.3
COLUMNS = ("fitted", "shipped", "gated", "blended")


def fit_range_of(work: Path, meta) -> FitRange:  # type: ignore[no-untyped-def]
    """The range the model records, or (fitted before it did) that of the same stretches."""
    carried = Uncertainty.from_dict(meta.uncertainty).fit_range
    if carried is not None:
        return carried
    own, _ = load_runs([work / "own"], step_s=meta.dt_s)
    head, _ = split_in_time(own, TEST_FRACTION, "test")
    inputs = ("x_v_mps", "y_a_mps2", "yaw_rate_radps")
    samples = (np.concatenate([getattr(r.samples, n) for r in head]) for n in inputs)
    return FitRange.of_samples(*samples, outside_scale=1.0, window_steps=meta.window_steps)


def main(argv: list[str] | None = None) -> int:
    p = study_parser(__doc__)
    args = p.parse_args(argv)
    start_net, start_meta = load_model(resolve(START))
    summary: dict[str, dict[str, float]] = {}
    for work in args.cars:
        net, meta = load_model(work / "fitted.safetensors")
        fit_range = fit_range_of(work, meta)
        car = fitted_car(work)
        drives, _ = load_runs(sorted(args.drives.glob(f"{work.name}_*")), step_s=meta.dt_s)
        fitted, shipped, beyond = [], [], []
        w = meta.window_steps
        for run in drives:
            s = run.samples
            mine = predict_run(net, meta, run, **car)
            start = predict_run(start_net, start_meta, run, **car)
            ref = s.beta_rad()[w - 1 :]
            ok = np.isfinite(mine) & np.isfinite(start) & np.isfinite(ref)
            fitted.append((mine - ref)[ok])
            shipped.append((start - ref)[ok])
            flags = fit_range.window_beyond(s.x_v_mps, s.y_a_mps2, s.yaw_rate_radps)
            beyond.append(flags[w - 1 :][ok])
        f, sh, b = (np.concatenate(x) for x in (fitted, shipped, beyond))
        errors = {
            "fitted": f,
            "shipped": sh,
            "gated": np.where(b, sh, f),
            "blended": np.where(b, 0.5 * (sh + f), f),
        }
        mae = {k: float(np.degrees(np.abs(e)).mean()) for k, e in errors.items()}
        mae["beyond share"] = float(b.mean())
        if b.any():
            mae["fitted beyond"] = float(np.degrees(np.abs(f[b])).mean())
            mae["shipped beyond"] = float(np.degrees(np.abs(sh[b])).mean())
        mae["fitted within"] = float(np.degrees(np.abs(f[~b])).mean())
        mae["shipped within"] = float(np.degrees(np.abs(sh[~b])).mean())
        summary[work.name] = mae
        print(work.name, json.dumps({k: round(v, 4) for k, v in mae.items()}), flush=True)
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    print("| car | window beyond | fitted | shipped | gated | fitted / shipped within | "
          "fitted / shipped beyond |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for name, m in summary.items():
        beyond_pair = (
            f"{m['fitted beyond']:.4f} / {m['shipped beyond']:.4f}" if "fitted beyond" in m else "—"
        )
        print(f"| {name} | {m['beyond share']:.3f} | {m['fitted']:.4f} | {m['shipped']:.4f} | "
              f"{m['gated']:.4f} | {m['fitted within']:.4f} / {m['shipped within']:.4f} | "
              f"{beyond_pair} |")  # fmt: skip
    means = {k: float(np.mean([m[k] for m in summary.values()])) for k in COLUMNS}
    worse = sum(m["fitted"] > m["shipped"] for m in summary.values())
    print(f"| mean | | {means['fitted']:.4f} | {means['shipped']:.4f} | {means['gated']:.4f} | "
          f"fitted worse than shipped on {worse} of {len(summary)} cars | |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
