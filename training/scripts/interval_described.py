"""Does a UKF-anchored model need its own σ for car files made from a description?
(validation cars only).

A model that reads the UKF is calibrated with each validation car's true ``ukf`` file.
Given a file that ``sideslip-fit`` writes from a short description instead (the fleet's
typical tyres, no measured axles), its errors grow where the road is slippery, and the
σ terms cannot tell that car from one they know. This script measures that on the 16
benchmark-style validation cars (``data/val-benchmark``, ``data/val-benchmark-2``) with
the described files of ``described_validation.py`` (``data/dv-ens-a``, ``-b``), and
compares, 2-fold by car (fitted on cars 0–7, scored on the cells of cars 8–15, and the
other way round):

- the σ as the model file has it for true files (its own σ, also for the described
  files: what was published before a σ for described files existed);
- its terms, the scale refitted on the fit half's described-file errors (conformal 95 %);
- terms and scale refitted on them (likelihood on half the runs, scale on the rest, as
  ``sideslip-calibrate``).

The model's per-sample errors are cached in ``--cache`` (the ensemble over 16 cars ×
18 runs × 2 files takes most of an hour on 2 cores).

    python training/scripts/interval_described.py --model fleet_ukf_ensemble \\
        --cars data/dv-ens-a/fleet2_car* data/dv-ens-b/fleet2_car* \\
        --data data/val-benchmark data/val-benchmark-2 --cache data/interval-described.npz
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from sideslip_msgs_py.uncertainty import Uncertainty
from sideslip_msgs_py.vehicle_description import VehicleDescription
from sideslip_training.calibrate import Errors, conformal_scale, fit_coefficients, scale_of_ratios
from sideslip_training.dataset import Run, load_runs
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve

Z = 1.959963984540054
BAND = (0.93, 0.97)
FILES = ("true", "described")


def cars_and_runs(
    cars: list[Path], data: list[str], dt_s: float
) -> tuple[list[tuple[Path, list[Run], dict[str, Any]]], dict[str, dict[str, Any]]]:
    """Each car folder with its runs in ``data`` and the car files its description gives
    (as ``predict_run`` takes them); and every bag's index entry (its μ)."""
    runs, _ = load_runs(data, step_s=dt_s)
    index = {
        r["bag"]: r
        for folder in data
        for r in json.loads((Path(folder) / "index.json").read_text())["runs"]
    }
    out = []
    for car in cars:
        mine = [r for r in runs if index[Path(str(r.bag)).name]["vehicle"] == car.name]
        if not mine:
            raise SystemExit(f"{car}: no runs of {car.name} in {data}")
        described = {
            "vehicle": VehicleDescription.load(car / "description.yaml"),
            "observer_params_file": str(car / "described.ukf.yaml"),
            "car": "given",
        }
        out.append((car, mine, described))
    return out, index


def errors_by_car(model: str, cars: list[Path], data: list[str]) -> dict[str, np.ndarray]:
    """Per sample, over every car's runs and both files: error [rad], v, a_y, r, run
    (global index), car index, μ and which file (0 true, 1 described)."""
    net, meta = load_model(resolve(model))
    by_car, index = cars_and_runs(cars, data, meta.dt_s)
    out: dict[str, list[np.ndarray]] = {
        k: [] for k in ("err", "v", "ay", "r", "run", "car", "mu", "kind")
    }
    run_id = 0
    for ci, (car, mine, described) in enumerate(by_car):
        for fi, files in enumerate(({}, described)):
            for run in mine:
                e = Errors.of_runs([run], net, meta, **files)
                n = len(e)
                out["err"].append(e.err)
                out["v"].append(e.v)
                out["ay"].append(e.ay)
                out["r"].append(e.r)
                out["run"].append(np.full(n, run_id))
                out["car"].append(np.full(n, ci))
                out["mu"].append(np.full(n, float(index[Path(str(run.bag)).name]["mu"])))
                out["kind"].append(np.full(n, fi))
                run_id += 1
        print(f"{car.name}: {len(mine)} runs", file=sys.stderr, flush=True)
    return {k: np.concatenate(v) for k, v in out.items()}


def observer_terms(
    model: str, cars: list[Path], data: list[str], d: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """Per cached sample: the window means of the UKF's squared innovations (ψ̇ [rad/s],
    a_y [m/s²]) the model reads, in the cache's sample order (the scored samples are
    rebuilt as :meth:`Errors.of_runs` keeps them: a clean input window, a finite prior
    and reference; checked by count per run)."""
    from sideslip_training.inputs import InputSpec

    _, meta = load_model(resolve(model))
    names = list(meta.features)
    cols = [
        names.index("ukf.yaw_rate_innovation_radps"),
        names.index("ukf.lateral_acceleration_innovation_mps2"),
    ]
    by_car, _ = cars_and_runs(cars, data, meta.dt_s)
    w = meta.window_steps
    out: dict[str, list[np.ndarray]] = {"innr2w": [], "innay2w": []}
    run_id = 0
    for car, mine, described in by_car:
        for files in ({}, described):
            given = (files.get("vehicle"), meta.observer, files.get("observer_params_file"))
            car_source = str(files.get("car", "recorded"))
            spec = InputSpec(meta.features, meta.prior, meta.dt_s, *given, car=car_source)
            for run in mine:
                x = spec.inputs(run)
                prior = spec.prior_rad(run, w)[w - 1 :]
                bad = np.concatenate([[0], np.cumsum(~np.isfinite(x).all(axis=1))])
                ok = (
                    (bad[w:] - bad[:-w] == 0)
                    & np.isfinite(prior)
                    & np.isfinite(run.samples.beta_rad()[w - 1 :])
                )
                n = int((d["run"] == run_id).sum())
                if int(ok.sum()) != n:
                    raise SystemExit(f"{run.name}: {int(ok.sum())} rebuilt samples, {n} cached")
                for key, c in zip(("innr2w", "innay2w"), cols, strict=True):
                    sq = np.nan_to_num(x[:, c]) ** 2
                    cs = np.concatenate([[0.0], np.cumsum(sq)])
                    out[key].append(((cs[w:] - cs[:-w]) / w)[ok])
                run_id += 1
        print(f"{car.name}: observer terms", file=sys.stderr, flush=True)
    return {k: np.concatenate(v) for k, v in out.items()}


def sub(d: dict[str, np.ndarray], mask: np.ndarray) -> Errors:
    return Errors(d["err"][mask], d["v"][mask], d["ay"][mask], d["r"][mask], d["run"][mask])


def cells(
    d: dict[str, np.ndarray], mask: np.ndarray, unc: Uncertainty
) -> tuple[int, int, float, list[float]]:
    """Car × μ cells of ``mask`` in 93–97 %: count, cells, pooled share, per-cell shares."""
    e = sub(d, mask)
    inside = np.abs(e.err) <= Z * np.sqrt(e.variance(unc))
    car, mu = d["car"][mask], d["mu"][mask]
    shares = [
        float(inside[(car == c) & (mu == m)].mean())
        for c in np.unique(car)
        for m in np.unique(mu)
        if ((car == c) & (mu == m)).any()
    ]
    n = sum(BAND[0] <= s <= BAND[1] for s in shares)
    return n, len(shares), float(inside.mean()), shares


def summary(key: str, pooled: list[float], per_cell: list[float]) -> dict[str, object]:
    """The figures of one σ over the scored cells of both folds, printed as one line."""
    inside = sum(BAND[0] <= x <= BAND[1] for x in per_cell)
    below = sum(x < BAND[0] for x in per_cell)
    print(f"{key:55s} cells {inside}/{len(per_cell)} (under 93 %: {below})  pooled "
          f"{pooled[0]:.3f} / {pooled[1]:.3f}  cell min {min(per_cell):.3f} median "
          f"{np.median(per_cell):.3f}")  # fmt: skip
    return {
        "cells_in_band": inside,
        "cells_under_band": below,
        "cells": len(per_cell),
        "pooled_per_fold": pooled,
        "cell_min": min(per_cell),
        "cell_median": float(np.median(per_cell)),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="fleet_ukf_ensemble")
    p.add_argument(
        "--cars",
        nargs="+",
        type=Path,
        required=True,
        help="folders with true.ukf.yaml and described.ukf.yaml",
    )
    p.add_argument("--data", nargs="+", required=True, help="benchmark-style validation bags")
    p.add_argument("--cache", type=Path, required=True, help=".npz of the per-sample errors")
    p.add_argument("--out", type=Path, help="JSON of the figures")
    p.add_argument(
        "--observer-terms",
        type=Path,
        help=".npz cache of the UKF innovation terms: also score σ with them",
    )
    args = p.parse_args(argv)
    cars = sorted(args.cars, key=lambda c: c.name)
    if args.cache.exists():
        d = dict(np.load(args.cache))
    else:
        d = errors_by_car(args.model, cars, args.data)
        np.savez_compressed(args.cache, **d)
    _, meta = load_model(resolve(args.model))
    shipped = Uncertainty.from_dict(meta.uncertainty)
    half = len(cars) // 2
    folds = [
        (np.arange(half), np.arange(half, len(cars))),
        (np.arange(half, len(cars)), np.arange(half)),
    ]
    result: dict[str, dict[str, object]] = {}
    for fi, kind in enumerate(FILES):
        for label in ("as shipped", "scale refitted", "terms and scale refitted"):
            total_in = total = 0
            pooled: list[float] = []
            per_cell: list[float] = []
            for fit_cars, score_cars in folds:
                fit_mask = np.isin(d["car"], fit_cars) & (d["kind"] == fi)
                score_mask = np.isin(d["car"], score_cars) & (d["kind"] == fi)
                if label == "as shipped":
                    unc = shipped
                elif label == "scale refitted":
                    unc = Uncertainty(
                        shipped.coefficients,
                        conformal_scale(sub(d, fit_mask), shipped.coefficients, 0.95),
                    )
                else:
                    runs = np.unique(d["run"][fit_mask])
                    order = np.random.default_rng(0).permutation(runs)
                    a = fit_mask & np.isin(d["run"], order[::2])
                    b = fit_mask & np.isin(d["run"], order[1::2])
                    c = fit_coefficients(sub(d, a))
                    unc = Uncertainty(c, conformal_scale(sub(d, b), c, 0.95))
                n, k, pool, shares = cells(d, score_mask, unc)
                total_in, total = total_in + n, total + k
                pooled.append(pool)
                per_cell += shares
            key = f"{kind} file, σ {label}"
            result[key] = summary(key, pooled, per_cell)
    if args.observer_terms:
        if args.observer_terms.exists():
            d.update(dict(np.load(args.observer_terms)))
        else:
            extra = observer_terms(args.model, cars, args.data, d)
            np.savez_compressed(args.observer_terms, **extra)
            d.update(extra)
        result.update(with_observer_terms(d, folds))
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")
    return 0


OBSERVER_SETS = {
    "+ window mean of a_y innovation²": ["innay2w"],
    "+ window mean of ψ̇ innovation²": ["innr2w"],
    "+ both innovations²": ["innr2w", "innay2w"],
}


def with_observer_terms(d: dict[str, np.ndarray], folds) -> dict[str, dict[str, object]]:  # type: ignore[no-untyped-def]
    """The shipped terms plus the UKF's innovations (window means), terms and scale
    refitted per kind of file as above: what a σ that sees how wrong the filter's car
    is would do."""
    from interval_terms import fit

    from sideslip_msgs_py.uncertainty import terms

    base = terms(d["v"], d["ay"], d["r"])
    result = {}
    for fi, kind in enumerate(FILES):
        for label, keys in OBSERVER_SETS.items():
            t = np.concatenate([base, np.stack([d[k] for k in keys], axis=1)], axis=1)
            total_in = total = 0
            pooled, per_cell = [], []
            for fit_cars, score_cars in folds:
                fit_mask = np.isin(d["car"], fit_cars) & (d["kind"] == fi)
                score_mask = np.isin(d["car"], score_cars) & (d["kind"] == fi)
                runs = np.unique(d["run"][fit_mask])
                order = np.random.default_rng(0).permutation(runs)
                a = fit_mask & np.isin(d["run"], order[::2])
                b = fit_mask & np.isin(d["run"], order[1::2])
                c = fit(t[a], d["err"][a] ** 2)
                scale = scale_of_ratios(np.abs(d["err"][b]) / np.sqrt(t[b] @ c), 0.95)
                inside = np.abs(d["err"]) <= Z * scale * np.sqrt(t @ c)
                shares = [
                    float(inside[score_mask & (d["car"] == cc) & (d["mu"] == m)].mean())
                    for cc in np.unique(d["car"][score_mask])
                    for m in np.unique(d["mu"][score_mask])
                ]
                total_in += sum(BAND[0] <= x <= BAND[1] for x in shares)
                total += len(shares)
                pooled.append(float(inside[score_mask].mean()))
                per_cell += shares
            key = f"{kind} file, σ terms {label}"
            result[key] = summary(key, pooled, per_cell)
    return result


if __name__ == "__main__":
    sys.exit(main())
