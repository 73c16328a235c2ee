"""Which per-sample terms make the 95 % interval hold per car and road (validation only).

The shipped default's σ model (``sideslip_msgs_py/uncertainty.py``) reads speed, lateral
acceleration and sideslip rate at the newest sample. This script asks whether other
terms a node could compute would make the interval hold in every car × μ cell, using the
validation fleet only (no held-out car): the model's errors on every validation run,
then for each candidate term set a 2-fold split by run: on one half, coefficients by
Gaussian likelihood on half its runs and the conformal scale on the rest (as
``sideslip-calibrate``), scored on the other half. Printed per term set: pooled
coverage, coverage per μ third, the share of cars and of car × μ cells (≥ 2000
samples) whose coverage lies in 93-97 %, and the held-back negative log-likelihood.

    python training/scripts/interval_terms.py --model fleet_lstm_paper --data data/fleet-val

``--members A B`` (for a ``sideslip-merge`` model) adds terms from how far apart its
members' estimates are.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from sideslip_msgs_py.uncertainty import Uncertainty
from sideslip_training.calibrate import scale_of_ratios
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve

Z = 1.959963984540054
SETS = {
    "shipped (1, 1/v², a_y², β̇²)": ["1", "1/v2", "ay2", "bdot2"],
    "+ window mean of β̇²": ["1", "1/v2", "ay2", "bdot2", "bdot2w"],
    "window means only": ["1", "1/v2", "ay2w", "bdot2w"],
    "+ β̂²": ["1", "1/v2", "ay2", "bdot2", "est2"],
    "window means + β̂²": ["1", "1/v2", "ay2w", "bdot2w", "est2"],
    "window means + β̂² + |a_y|": ["1", "1/v2", "ay2w", "bdot2w", "est2", "absay"],
    "1, 1/v², β̂²": ["1", "1/v2", "est2"],
}
# Terms from the UKF observer a model reads (its inputs at the sample): what the
# observer's model misses shows in its innovations, and the friction used in a_y / μ̂.
OBSERVER_SETS = {
    "+ window mean of ψ̇ innovation²": ["1", "1/v2", "ay2", "bdot2", "innr2w"],
    "+ window mean of a_y innovation²": ["1", "1/v2", "ay2", "bdot2", "innay2w"],
    "+ both innovations²": ["1", "1/v2", "ay2", "bdot2", "innr2w", "innay2w"],
    "+ (a_y / μ̂ g)²": ["1", "1/v2", "ay2", "bdot2", "ayfric2"],
    "+ μ̂²": ["1", "1/v2", "ay2", "bdot2", "muhat2"],
    "+ both innovations² + (a_y / μ̂ g)²": [
        "1",
        "1/v2",
        "ay2",
        "bdot2",
        "innr2w",
        "innay2w",
        "ayfric2",
    ],
}
# For a merged model (sideslip-merge), given its members (--members): how far apart the
# members' estimates are, at the sample and over the window.
MEMBER_SETS = {
    "+ members' spread²": ["1", "1/v2", "ay2", "bdot2", "spread2"],
    "+ window mean of members' spread²": ["1", "1/v2", "ay2", "bdot2", "spread2w"],
    "1, 1/v², window mean of members' spread²": ["1", "1/v2", "spread2w"],
}
MU_THIRDS = ((0.0, 0.5), (0.5, 0.8), (0.8, 1.01))


def samples(
    model: str, data: str | list[str], members: list[str] | None = None
) -> dict[str, np.ndarray]:
    """Per sample with a full window: error [rad], candidate term inputs, run, car, μ;
    with ``members`` also their spread (max − min of their β̂)."""
    net, meta = load_model(resolve(model))
    member_nets = [load_model(resolve(m)) for m in members or []]
    folders = [data] if isinstance(data, str) else list(data)
    runs, _ = load_runs(folders, step_s=meta.dt_s)
    index = {
        r["bag"]: r
        for folder in folders
        for r in json.loads((Path(folder) / "index.json").read_text())["runs"]
    }
    w = meta.window_steps
    cars: dict[str, int] = {}
    parts: list[dict[str, np.ndarray]] = []
    for i, run in enumerate(runs):
        est = predict_run(net, meta, run)
        s = run.samples
        v = np.maximum(s.x_v_mps, 1.0)
        bdot = s.y_a_mps2 / v - s.yaw_rate_radps

        def window_mean(x: np.ndarray) -> np.ndarray:
            c = np.concatenate([[0.0], np.cumsum(x)])
            return (c[w:] - c[:-w]) / w

        observed = observer_terms(meta, run, window_mean)
        if member_nets:
            each = np.array([predict_run(n, m, run) for n, m in member_nets])
            spread = np.nan_to_num(each.max(axis=0) - each.min(axis=0))
            full = np.concatenate([np.zeros(w - 1), spread**2])
            observed = {**observed, "spread2": spread**2, "spread2w": window_mean(full)}
        entry = index[Path(str(run.bag)).name]
        car = cars.setdefault(entry["vehicle"], len(cars))
        d = {
            "err": est - s.beta_rad()[w - 1 :],
            "1": np.ones(est.size),
            "1/v2": 1.0 / v[w - 1 :] ** 2,
            "ay2": s.y_a_mps2[w - 1 :] ** 2,
            "bdot2": bdot[w - 1 :] ** 2,
            "bdot2w": window_mean(bdot**2),
            "ay2w": window_mean(s.y_a_mps2**2),
            "est2": est**2,
            "absay": np.abs(s.y_a_mps2[w - 1 :]),
            "run": np.full(est.size, i),
            "car": np.full(est.size, car),
            "vehicle": np.full(est.size, entry["vehicle"]),
            "mu": np.full(est.size, float(entry["mu"])),
            **observed,
        }
        ok = np.isfinite(d["err"])
        parts.append({k: x[ok] for k, x in d.items()})
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def observer_terms(meta, run, window_mean) -> dict[str, np.ndarray]:  # type: ignore[no-untyped-def]
    """The observer's candidate terms per scored sample (none for a model without it)."""
    names = list(meta.features)
    wanted = ("ukf.yaw_rate_innovation_radps", "ukf.lateral_acceleration_innovation_mps2")
    if not all(n in names for n in (*wanted, "ukf.road_friction")):
        return {}
    from sideslip_training.inputs import InputSpec

    spec = InputSpec(meta.features, meta.prior, meta.dt_s, None, meta.observer)
    x = spec.inputs(run)
    w = meta.window_steps
    inn_r, inn_ay = (np.nan_to_num(x[:, names.index(n)]) for n in wanted)
    mu = np.maximum(np.nan_to_num(x[:, names.index("ukf.road_friction")], nan=1.0), 0.1)
    return {
        "innr2w": window_mean(inn_r**2),
        "innay2w": window_mean(inn_ay**2),
        "ayfric2": (run.samples.y_a_mps2[w - 1 :] / (mu[w - 1 :] * 9.81)) ** 2,
        "muhat2": mu[w - 1 :] ** 2,
    }


def fit(t: np.ndarray, e2: np.ndarray) -> np.ndarray:
    start = np.log(np.mean(e2) / (t.shape[1] * np.maximum(t.mean(axis=0), 1e-12)))

    def nll(log_c: np.ndarray) -> float:
        var = t @ np.exp(log_c)
        return float(0.5 * np.mean(np.log(var) + e2 / var))

    result = minimize(nll, start, method="Nelder-Mead", options={"maxiter": 8000, "fatol": 1e-12})
    return np.exp(result.x)


def shipped_sigma(model: str, d: dict[str, np.ndarray]) -> np.ndarray:
    """σ [rad] as the model file gives it (its four terms, coefficients and scale)."""
    _, meta = load_model(resolve(model))
    if meta.uncertainty is None:
        raise SystemExit(f"{model}: the model stores no σ model")
    u = Uncertainty.from_dict(meta.uncertainty)
    t = np.stack([d[k] for k in SETS["shipped (1, 1/v², a_y², β̇²)"]], axis=1)
    return u.scale * np.sqrt(t @ np.asarray(u.coefficients))


def cells_in_band(inside: np.ndarray, d: dict[str, np.ndarray]) -> tuple[int, int, dict[str, int]]:
    """Car × μ cells (exact μ, as the benchmark drives them) in 93-97 %: count, cells,
    and the count per μ."""
    count, total, per_mu = 0, 0, {}
    for mu in np.unique(d["mu"]):
        for c in np.unique(d["car"]):
            m = (d["car"] == c) & (d["mu"] == mu)
            if not m.any():
                continue
            ok = 0.93 <= inside[m].mean() <= 0.97
            count, total = count + ok, total + 1
            per_mu[f"{mu:.1f}"] = per_mu.get(f"{mu:.1f}", 0) + ok
    return count, total, per_mu


def per_car(inside: np.ndarray, d: dict[str, np.ndarray], cars: np.ndarray) -> str:
    """Cars (of ``cars``) whose pooled share lies in 93-97 %, and the lowest share."""
    shares = np.array([inside[d["car"] == c].mean() for c in cars])
    good = int(np.sum((shares >= 0.93) & (shares <= 0.97)))
    return f"cars {good}/{cars.size} (min {shares.min():.3f})"


def score_other_cars(
    model: str,
    fit_data: list[str],
    score_data: list[str],
    check: list[str] | None = None,
    members: list[str] | None = None,
) -> None:
    """Coefficients by likelihood on half of ``fit_data``'s runs, the conformal scale on
    the other half; scored per car × μ cell on ``score_data`` (other cars), and per car
    on ``check``'s cars that ``fit_data`` does not hold (other driving, e.g. fleet-style)."""
    d = samples(model, fit_data, members)
    e = samples(model, score_data, members)
    f = samples(model, check, members) if check else None
    if f is not None:
        seen = set(np.unique(d["vehicle"]))
        f_cars = np.unique(f["car"][~np.isin(f["vehicle"], list(seen))])
    runs = np.unique(d["run"])
    order = np.random.default_rng(0).permutation(runs)
    fit_rows, scale_rows = np.isin(d["run"], order[::2]), np.isin(d["run"], order[1::2])
    print(f"fit on {runs.size} runs, scored on {np.unique(e['run']).size} runs of other cars")
    inside = np.abs(e["err"]) <= Z * shipped_sigma(model, e)
    n, total, per_mu = cells_in_band(inside, e)
    label = "as the model file has it"
    extra = ""
    if f is not None:
        extra = "; check " + per_car(np.abs(f["err"]) <= Z * shipped_sigma(model, f), f, f_cars)
    print(f"{label:40s} pooled {inside.mean():.3f}; cells {n}/{total} {per_mu}{extra}")
    sets = {
        **SETS,
        **(OBSERVER_SETS if "innr2w" in d else {}),
        **(MEMBER_SETS if "spread2" in d else {}),
    }
    for name, keys in sets.items():
        t = np.stack([d[k] for k in keys], axis=1)
        c = fit(t[fit_rows], d["err"][fit_rows] ** 2)
        scale = scale_of_ratios(np.abs(d["err"][scale_rows]) / np.sqrt(t[scale_rows] @ c), 0.95)
        sigma = scale * np.sqrt(np.stack([e[k] for k in keys], axis=1) @ c)
        inside = np.abs(e["err"]) <= Z * sigma
        n, total, per_mu = cells_in_band(inside, e)
        extra = ""
        if f is not None:
            f_sigma = scale * np.sqrt(np.stack([f[k] for k in keys], axis=1) @ c)
            extra = "; check " + per_car(np.abs(f["err"]) <= Z * f_sigma, f, f_cars)
        print(f"{name:40s} pooled {inside.mean():.3f}; cells {n}/{total} {per_mu}{extra}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", default="fleet_lstm_paper")
    parser.add_argument(
        "--data", nargs="+", default=["data/fleet-val"], help="validation bags (index.json)"
    )
    parser.add_argument(
        "--score",
        nargs="+",
        help="score on these bags (other validation cars) per car × μ cell, fitting on --data",
    )
    parser.add_argument(
        "--check", nargs="+", help="with --score: also per car on these bags' other cars"
    )
    parser.add_argument(
        "--members", nargs="+", help="a merged model's members: adds their spread as terms"
    )
    args = parser.parse_args(argv)
    if args.score:
        score_other_cars(args.model, args.data, args.score, args.check, args.members)
        return 0
    d = samples(args.model, args.data, args.members)
    runs = d["run"]
    order = np.random.default_rng(0).permutation(np.unique(runs))
    folds = (order[::2], order[1::2])
    print(f"{runs.size} samples, {np.unique(runs).size} runs, {np.unique(d['car']).size} cars")
    sets = {
        **SETS,
        **(OBSERVER_SETS if "innr2w" in d else {}),
        **(MEMBER_SETS if "spread2" in d else {}),
    }
    for name, keys in sets.items():
        t = np.stack([d[k] for k in keys], axis=1)
        inside = np.zeros(runs.size, bool)
        for k in range(2):
            held = ~np.isin(runs, folds[k])
            fit_rows, scale_rows = np.isin(runs, folds[k][::2]), np.isin(runs, folds[k][1::2])
            sigma = np.sqrt(t @ fit(t[fit_rows], d["err"][fit_rows] ** 2))
            scale = scale_of_ratios(np.abs(d["err"][scale_rows]) / sigma[scale_rows], 0.95)
            inside[held] = np.abs(d["err"][held]) <= Z * scale * sigma[held]
        thirds = [inside[(d["mu"] >= lo) & (d["mu"] < hi)].mean() for lo, hi in MU_THIRDS]
        per_car = np.array([inside[d["car"] == c].mean() for c in np.unique(d["car"])])
        cells = np.array(
            [
                inside[m].mean()
                for c in np.unique(d["car"])
                for lo, hi in MU_THIRDS
                if (m := (d["car"] == c) & (d["mu"] >= lo) & (d["mu"] < hi)).sum() >= 2000
            ]
        )

        def share(x: np.ndarray) -> float:
            return float(np.mean((x >= 0.93) & (x <= 0.97)))

        print(
            f"{name:30s} pooled {inside.mean():.3f}; μ thirds "
            + " ".join(f"{x:.3f}" for x in thirds)
            + f"; cars in 93-97 % {share(per_car):.2f} (min {per_car.min():.3f}); "
            f"car × μ cells in 93-97 % {share(cells):.2f} of {cells.size}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
