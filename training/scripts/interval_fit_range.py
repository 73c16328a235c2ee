"""Does a fitted model's σ hold better if it stops trusting the car's own scale beyond
the driving it was fitted on? A study on ``fit_bags_check.py``'s validation cars.

A model out of ``sideslip-fit --bags`` carries the start model's σ terms with a scale
fitted on the car's own validation stretch (``--intervals auto``). Its errors shrink
where the own driving taught it; they do not where the driving goes beyond it (a limit
manoeuvre the recordings lack), and there the car's scale is too narrow. Since
``sideslip-train`` records the recordings' range (the 99.9th percentile of |a_y| and of
|β̇| = |a_y / X_v − ψ̇| over the training and validation stretches), σ takes ``--factor``
times the start model's scale, when wider, while the network's input window reaches
beyond it.

Share of samples inside ±1.96 σ of the fitted model's errors, per car and per run, on
the card's test part (each own recording's last 30 %) and on the car's four
validation-fleet drives (new drives), for the car's scale alone and with the range at
each factor. Models fitted before the range was recorded get it here from the same
stretches. Writes ``OUT`` (JSON), prints markdown tables; each car's ``fit_range`` in
``OUT`` is the model's own (``outside_scale`` 2 × the start's) or, for those older
models, the one made here (``outside_scale`` 1 × the start's): either way the factors
multiply the start model's scale.

    python training/scripts/interval_fit_range.py --cars data/fit-bags-check/fleet2_car00{0..3} \
        data/fit-bags-check-b/fleet2_car00{4..7} --drives data/fleet-val --out FILE.json

The held-out cars (``--drives data/held-out``) are grouped by μ cell instead of run.
"""

from __future__ import annotations

import json
import re
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.uncertainty import Z_95, FitRange, Uncertainty
from sideslip_training.dataset import Run, load_runs
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve
from sideslip_training.splits import split_in_time

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_folder import fitted_car, study_parser

START = "fleet_ukf_measurable"
TEST_FRACTION = 0.3
WHERE = ("test part", "new drives")
BAND = (0.93, 0.97)
MU = re.compile(r"_mu(\d\d)_")


@dataclass(frozen=True)
class Scored:
    """One run's scored samples: error [rad] and the σ² of every variant [rad²]."""

    name: str
    err: npt.NDArray[np.float64]
    variances: dict[str, npt.NDArray[np.float64]]
    beyond: npt.NDArray[np.bool_]


def score(runs: list[Run], net, meta, variants: dict[str, Uncertainty], car) -> list[Scored]:  # type: ignore[no-untyped-def]
    """Each run's errors and σ² as ``sideslip-evaluate`` computes them (σ over the whole
    run, so the first window sees what came before it)."""
    out = []
    w = meta.window_steps
    for run in runs:
        s = run.samples
        est = predict_run(net, meta, run, **car)
        ref = s.beta_rad()[w - 1 :]
        ok = np.isfinite(est) & np.isfinite(ref)
        inputs = (s.x_v_mps, s.y_a_mps2, s.yaw_rate_radps)
        var = {k: u.variance(*inputs)[w - 1 :][ok] for k, u in variants.items()}
        some_range = next(u.fit_range for u in variants.values() if u.fit_range is not None)
        beyond = some_range.window_beyond(*inputs)[w - 1 :][ok]
        out.append(Scored(run.name, (est - ref)[ok], var, beyond))
    return out


def shares(scored: list[Scored], variant: str, group) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """Share inside ±1.96 σ per group of runs (``group(name)``), and ``pooled``."""
    acc: dict[str, list[npt.NDArray[np.bool_]]] = {}
    for r in scored:
        inside = np.abs(r.err) <= Z_95 * np.sqrt(r.variances[variant])
        acc.setdefault(group(r.name), []).append(inside)
        acc.setdefault("pooled", []).append(inside)
    return {k: float(np.concatenate(v).mean()) for k, v in acc.items()}


def cell(name: str) -> str:
    """A held-out run's μ cell (``mu10``), else the run itself."""
    found = MU.search(name)
    return f"mu{found.group(1)}" if found else name


def main(argv: list[str] | None = None) -> int:
    p = study_parser(__doc__)
    p.add_argument("--factors", type=float, nargs="+", default=[1.0, 1.5, 2.0, 3.0])
    args = p.parse_args(argv)
    _, start_meta = load_model(resolve(START))
    start_scale = Uncertainty.from_dict(start_meta.uncertainty).scale
    summary: dict[str, dict] = {}
    for work in args.cars:
        net, meta = load_model(work / "fitted.safetensors")
        carried = Uncertainty.from_dict(meta.uncertainty)
        car = fitted_car(work)
        own, _ = load_runs([work / "own"], step_s=meta.dt_s)
        head, tail = split_in_time(own, TEST_FRACTION, "test")
        fit_range = carried.fit_range or FitRange.of_samples(
            *(
                np.concatenate([getattr(r.samples, name) for r in head])
                for name in ("x_v_mps", "y_a_mps2", "yaw_rate_radps")
            ),
            outside_scale=start_scale,
            window_steps=meta.window_steps,
        )
        variants = {"car's scale": replace(carried, fit_range=None)} | {
            f"× {k:g}": replace(
                carried, fit_range=replace(fit_range, outside_scale=k * start_scale)
            )
            for k in args.factors
        }
        tail = [r for r in tail if len(r.samples) >= meta.window_steps]
        drives, _ = load_runs(sorted(args.drives.glob(f"{work.name}_*")), step_s=meta.dt_s)
        row: dict[str, dict] = {"fit_range": fit_range.to_dict(), "scale": carried.scale}
        for where, runs in zip(WHERE, (tail, drives), strict=True):
            scored = score(runs, net, meta, variants, car)
            beyond = np.concatenate([r.beyond for r in scored])
            err = np.degrees(np.abs(np.concatenate([r.err for r in scored])))
            row[where] = {
                "inside": {k: shares(scored, k, cell) for k in variants},
                "runs": {k: shares(scored, k, lambda n: n) for k in variants},
                "beyond share": float(beyond.mean()),
                "mae beyond / within": [
                    float(err[beyond].mean()) if beyond.any() else None,
                    float(err[~beyond].mean()),
                ],
            }
        summary[work.name] = row
        print(work.name, json.dumps({w: row[w]["inside"] for w in WHERE}), flush=True)
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    names = list(next(iter(summary.values()))[WHERE[0]]["inside"])
    print("| car | where | window beyond the range | MAE beyond / within [deg] | "
          + " | ".join(names) + " |")  # fmt: skip
    print("|---|---|---|---|" + "---|" * len(names))
    for name, row in summary.items():
        for where in WHERE:
            r = row[where]
            mae = " / ".join("—" if x is None else f"{x:.3f}" for x in r["mae beyond / within"])
            cells = " | ".join(f"{r['inside'][k]['pooled']:.3f}" for k in names)
            print(f"| {name} | {where} | {r['beyond share']:.3f} | {mae} | {cells} |")
    print()
    print("| σ | where | mean \\|share − 0.95\\| over cars | worst car | cars in 93–97 % "
          "| groups in 93–97 % | groups under 93 % | worst group |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for k in names:
        for where in WHERE:
            cars = [row[where]["inside"][k]["pooled"] for row in summary.values()]
            by = "inside" if where == "new drives" else "runs"
            groups = [
                v for row in summary.values() for g, v in row[where][by][k].items() if g != "pooled"
            ]
            band = lambda xs: sum(BAND[0] <= x <= BAND[1] for x in xs)  # noqa: E731
            dev = float(np.mean([abs(x - 0.95) for x in cars]))
            print(f"| {k} | {where} | {dev:.3f} | {min(cars):.3f} | {band(cars)}/{len(cars)} | "
                  f"{band(groups)}/{len(groups)} | {sum(x < BAND[0] for x in groups)} | "
                  f"{min(groups):.3f} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
