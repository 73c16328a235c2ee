"""A learnt σ: a small LSTM that reads the model's own input window and answers log σ²,
trained by Gaussian negative log-likelihood on the model's errors (validation only).

Issue 9 asks for σ from "a Gaussian negative-log-likelihood head, an ensemble, or
conformal calibration: choose by measurement". The ensemble's spread and conformal
scales over per-sample terms were measured (docs/evaluation/intervals); this is the
third. The β network stays as it is (its estimate is what the node publishes, averaged
with its mirror image); a second network of the same kind (``SideslipNet``, so the
node's engines could run it as they run an ensemble member) learns how large that
estimate's error is from the same z-scored window. Its σ is then scaled conformally to
95 % on other runs, as ``sideslip-calibrate`` scales the terms.

Protocol, as ``interval_terms.py --score`` both ways round: each ``--folds`` folder
(benchmark-style drives of a group of validation cars) is scored per car × μ cell
(93-97 %), fitted on the other folds and ``--extra`` (fleet-style drives) without that
fold's cars; the fit is split by run (half trains the σ network, a quarter stops it
early, a quarter sets the scale; the terms take the first three quarters). Compared: the
model file's σ, the same four terms fitted on fleet-style drives only (as the shipped UKF
models were) and on both kinds, and the σ network (``--hidden``). The extra folder's
drives of the scored cars give a per-car check on fleet-style driving.

    python training/scripts/interval_sigma_net.py --model fleet_ukf_paper \\
        --folds data/val-benchmark data/val-benchmark-2 --extra data/fleet-val \\
        --hidden 16 32 --seeds 0 1 2
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

from sideslip_msgs_py.artifact import zscore
from sideslip_msgs_py.uncertainty import Uncertainty, terms
from sideslip_training.calibrate import scale_of_ratios
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve
from sideslip_training.inputs import InputSpec
from sideslip_training.model import ModelConfig, SideslipNet

sys.path.insert(0, str(Path(__file__).parent))
from interval_terms import Z, fit  # a sibling script: the same likelihood fit


def gather(model: str, folders: list[str], inputs: bool = True) -> list[dict]:
    """Per run: the z-scored inputs (float32), the published estimate's error [rad] at
    samples[w-1:], the four σ terms there, its car and μ."""
    net, meta = load_model(resolve(model))
    runs, _ = load_runs(folders, step_s=meta.dt_s)
    index = {
        r["bag"]: r
        for f in folders
        for r in json.loads((Path(f) / "index.json").read_text())["runs"]
    }
    w = meta.window_steps
    out = []
    for run in runs:
        x = None
        if inputs:
            spec = InputSpec(meta.features, meta.prior, meta.dt_s, None, meta.observer)
            x = zscore(spec.inputs(run), meta.feature_mean, meta.feature_std).astype(np.float32)
        est = predict_run(net, meta, run, mirror_average="auto")
        s = run.samples
        entry = index[Path(str(run.bag)).name]
        out.append(
            {
                "x": None if x is None else np.nan_to_num(x),
                "err": est - s.beta_rad()[w - 1 :],
                "terms": terms(s.x_v_mps[w - 1 :], s.y_a_mps2[w - 1 :], s.yaw_rate_radps[w - 1 :]),
                "vehicle": entry["vehicle"],
                "mu": float(entry["mu"]),
            }
        )
    return out


def windows(runs: list[dict], w: int, stride: int) -> tuple[np.ndarray, np.ndarray]:
    """(N, w, F) windows ending every ``stride`` samples with a finite error, and errors."""
    xs, es = [], []
    for r in runs:
        ends = np.arange(0, r["err"].size, stride)
        ends = ends[np.isfinite(r["err"][ends])]
        view = np.lib.stride_tricks.sliding_window_view(r["x"], w, axis=0)  # (N, F, w)
        xs.append(view[ends].transpose(0, 2, 1))
        es.append(r["err"][ends])
    return np.concatenate(xs).astype(np.float32), np.concatenate(es)


def train_sigma_net(
    train: list[dict], stop: list[dict], w: int, hidden: int, epochs: int, seed: int
) -> tuple[SideslipNet, float]:
    """The σ network (output: log of σ² / e_rms²) by Gaussian NLL, best epoch on ``stop``."""
    torch.manual_seed(seed)
    xt, et = windows(train, w, 10)
    xs, es = windows(stop, w, 25)
    e_rms = float(np.sqrt(np.mean(et**2)))
    net = SideslipNet(ModelConfig(n_features=xt.shape[2], hidden_units=hidden))
    opt = torch.optim.Adam(net.parameters(), lr=3e-3)
    xt_t, et_t = torch.from_numpy(xt), torch.from_numpy((et / e_rms).astype(np.float32))
    xs_t, es_t = torch.from_numpy(xs), torch.from_numpy((es / e_rms).astype(np.float32))

    def nll(s: torch.Tensor, e: torch.Tensor) -> torch.Tensor:
        return 0.5 * (s + e**2 * torch.exp(-s)).mean()

    best, best_state = np.inf, None
    gen = torch.Generator().manual_seed(seed)
    for epoch in range(epochs):
        net.train()
        t0 = time.time()
        for idx in torch.randperm(xt_t.shape[0], generator=gen).split(512):
            opt.zero_grad()
            loss = nll(net(xt_t[idx]), et_t[idx])
            loss.backward()
            opt.step()
        net.eval()
        with torch.inference_mode():
            val = float(
                sum(
                    nll(net(xs_t[i]), es_t[i]) * len(i) for i in torch.arange(len(xs_t)).split(4096)
                )
                / len(xs_t)
            )
        print(f"  epoch {epoch + 1}: stop-set NLL {val:.4f} ({time.time() - t0:.0f} s)", flush=True)
        if val < best:
            best, best_state = val, {k: v.clone() for k, v in net.state_dict().items()}
    assert best_state is not None
    net.load_state_dict(best_state)
    return net, e_rms


def net_sigma(net: SideslipNet, e_rms: float, run: dict, w: int) -> np.ndarray:
    """σ [rad] (before the conformal scale) at every scored sample of ``run``."""
    view = np.lib.stride_tricks.sliding_window_view(run["x"], w, axis=0)
    out = np.empty(view.shape[0])
    with torch.inference_mode():
        for s in range(0, view.shape[0], 2048):
            chunk = torch.from_numpy(np.ascontiguousarray(view[s : s + 2048].transpose(0, 2, 1)))
            out[s : s + chunk.shape[0]] = net(chunk).numpy()
    return e_rms * np.exp(0.5 * out)


def fit_terms(runs: list[dict]) -> np.ndarray:
    """The four terms' coefficients by Gaussian likelihood on ``runs``' finite errors."""
    t = np.concatenate([r["terms"] for r in runs])
    e2 = np.concatenate([r["err"] for r in runs]) ** 2
    ok = np.isfinite(e2)
    return fit(t[ok], e2[ok])


def cells(score: list[dict], sigma: list[np.ndarray]) -> tuple[int, int, float, list]:
    """Car × μ cells in 93-97 % (runs pooled by samples), their count, pooled share."""
    by_cell: dict[tuple[str, str, float], list[np.ndarray]] = {}
    for r, s in zip(score, sigma, strict=True):
        ok = np.isfinite(r["err"])
        key = (r["folder"], r["vehicle"], r["mu"])
        by_cell.setdefault(key, []).append(np.abs(r["err"][ok]) <= Z * s[ok])
    shares = {k: float(np.concatenate(v).mean()) for k, v in sorted(by_cell.items())}
    good = sum(0.93 <= x <= 0.97 for x in shares.values())
    pooled = float(np.concatenate([x for v in by_cell.values() for x in v]).mean())
    return good, len(shares), pooled, [[*k, round(x, 4)] for k, x in shares.items()]


def per_car(runs: list[dict], sigma: list[np.ndarray]) -> dict[str, float]:
    """Share inside ±1.96 σ per car, its runs pooled by samples."""
    by_car: dict[str, list[np.ndarray]] = {}
    for r, s in zip(runs, sigma, strict=True):
        ok = np.isfinite(r["err"])
        by_car.setdefault(r["vehicle"], []).append(np.abs(r["err"][ok]) <= Z * s[ok])
    return {k: round(float(np.concatenate(v).mean()), 4) for k, v in sorted(by_car.items())}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", default="fleet_ukf_paper")
    parser.add_argument(
        "--folds",
        nargs="+",
        required=True,
        help="benchmark-style validation bags, one fold per group of cars (folders of the "
        "same cars joined by commas, e.g. level and crossfall): each fold is scored per "
        "folder × car × μ cell in turn, fitted on the others and --extra",
    )
    parser.add_argument(
        "--extra",
        nargs="*",
        default=[],
        help="other validation bags (fleet-style drives) fitted on; their runs of a fold's "
        "cars are left out of that fold's fit and scored per car as the check",
    )
    parser.add_argument(
        "--hidden", type=int, nargs="*", default=[], help="σ network sizes (none: terms only)"
    )
    parser.add_argument("--epochs", type=int, default=6)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0], help="run splits")
    parser.add_argument("--out", type=Path, help="JSON report")
    args = parser.parse_args(argv)
    torch.set_num_threads(2)
    _, meta = load_model(resolve(args.model))
    w = meta.window_steps
    t0 = time.time()
    folds = [fold.split(",") for fold in args.folds]
    folders = [*(f for fold in folds for f in fold), *args.extra]
    gathered = {f: gather(args.model, [f], inputs=bool(args.hidden)) for f in folders}
    for f, runs in gathered.items():
        for r in runs:
            r["kind"] = "extra" if f in args.extra else "fold"
            r["folder"] = Path(f).name
    print(f"gathered {sum(map(len, gathered.values()))} runs ({time.time() - t0:.0f} s)")
    report: dict = {"model": args.model, "folds": args.folds, "extra": args.extra, "rows": []}
    u = None if meta.uncertainty is None else Uncertainty.from_dict(meta.uncertainty)
    for seed in args.seeds:
        for fold in folds:
            score_runs = [r for f in fold for r in gathered[f]]
            cars = {r["vehicle"] for r in score_runs}
            fit_runs = [
                r for f in folders if f not in fold for r in gathered[f] if r["vehicle"] not in cars
            ]
            check_runs = [r for f in args.extra for r in gathered[f] if r["vehicle"] in cars]
            print(f"seed {seed}, scored {','.join(fold)}: fitted on {len(fit_runs)} runs")
            for row in compare(fit_runs, score_runs, check_runs, u, args, w, seed):
                report["rows"].append({"seed": seed, "scored": ",".join(fold), **row})
            if args.out:
                args.out.write_text(json.dumps(report, indent=1))
    summary: dict[str, list[int]] = {}
    for row in report["rows"]:
        summary.setdefault(row["name"], []).append(row["cells_in_band"])
    print("cells in 93-97 % summed over folds, mean over seeds:")
    for name, counts in summary.items():
        total = sum(counts) / len(args.seeds)
        print(f"  {name:44s} {total:.1f} (runs {counts})")
    report["summary"] = summary
    if args.out:
        args.out.write_text(json.dumps(report, indent=1))
    return 0


def compare(fit_runs, score_runs, check_runs, u, args, w, seed):  # type: ignore[no-untyped-def]
    """Rows (name, cells in band, pooled, per cell, check per car) for each σ."""
    order = np.random.default_rng(seed).permutation(len(fit_runs))
    train = [fit_runs[i] for i in order[::2]]
    stop = [fit_runs[i] for i in order[1::4]]
    scale_set = [fit_runs[i] for i in order[3::4]]
    rows = []

    def record(name: str, sigma_of) -> None:  # type: ignore[no-untyped-def]
        good, total, pooled, per_cell = cells(score_runs, [sigma_of(r) for r in score_runs])
        row = {"name": name, "cells_in_band": good, "cells": total, "pooled": pooled}
        row["per_cell"] = per_cell
        extra = ""
        if check_runs:
            shares = per_car(check_runs, [sigma_of(r) for r in check_runs])
            vals = np.array(list(shares.values()))
            n_ok = int(np.sum((vals >= 0.93) & (vals <= 0.97)))
            extra = f"; fleet-style: cars {n_ok}/{vals.size} in band (min {vals.min():.3f})"
            row["check_per_car"] = shares
        print(f"  {name:44s} cells {good}/{total}, pooled {pooled:.3f}{extra}", flush=True)
        rows.append(row)

    def scaled(raw_fit: list[np.ndarray], runs: list[dict]) -> float:
        ratios = np.concatenate([np.abs(r["err"]) / s for r, s in zip(runs, raw_fit, strict=True)])
        return scale_of_ratios(ratios[np.isfinite(ratios)], 0.95)

    if u is not None:
        coef = np.asarray(u.coefficients)
        record("as the model file has it", lambda r: u.scale * np.sqrt(r["terms"] @ coef))
    for name, keep in (
        ("terms fitted on fleet-style drives only", lambda r: r["kind"] == "extra"),
        ("terms fitted on both kinds", lambda r: True),
    ):
        fit_set = [r for r in train + stop if keep(r)]
        scale_part = [r for r in scale_set if keep(r)]
        if not fit_set or not scale_part:
            continue
        c = fit_terms(fit_set)
        k = scaled([np.sqrt(r["terms"] @ c) for r in scale_part], scale_part)
        record(name, lambda r, c=c, k=k: k * np.sqrt(r["terms"] @ c))
    for hidden in args.hidden:
        t1 = time.time()
        net, e_rms = train_sigma_net(train, stop, w, hidden, args.epochs, seed)
        k = scaled([net_sigma(net, e_rms, r, w) for r in scale_set], scale_set)
        print(f"  σ network, {hidden} units: trained in {time.time() - t1:.0f} s")
        record(
            f"σ network, {hidden} units",
            lambda r, k=k, net=net, e_rms=e_rms: k * net_sigma(net, e_rms, r, w),
        )
    return rows


if __name__ == "__main__":
    sys.exit(main())
