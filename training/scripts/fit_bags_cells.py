"""Per car × μ cell: the fitted and the shipped model's MAE and the share of samples
inside their published 95 % interval, from ``fit_bags_check.py --held-out`` reports
(each car's 18 held-out benchmark runs, scored with the identified axle file).

Pools the runs of a cell by sample count, as ``docs/evaluation/held-out`` does. Prints
markdown tables and writes ``--out`` (JSON).

    python training/scripts/fit_bags_cells.py --cars data/fit-bags-held-out*/heldout_* \
        --out docs/evaluation/fit-bags/held-out.json
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import numpy as np

FITTED, SHIPPED = "(fitted)", "(fleet_ukf_measurable)"
MU = re.compile(r"_mu(\d\d)_")


def cells(report: Path) -> dict[str, dict[str, dict[str, float]]]:
    """μ → estimator → pooled MAE [deg], coverage (NaN without σ) and samples."""
    acc: dict[str, dict[str, list[tuple[float, float, int]]]] = {}
    for r in json.loads((report / "metrics.json").read_text())["results"]:
        found = MU.search(r["scenario"])
        if found is None or r["mae"] is None:
            continue
        mu = f"{int(found.group(1)) / 10:.1f}"
        cov = r.get("coverage_95", float("nan"))
        acc.setdefault(mu, {}).setdefault(r["estimator"], []).append((r["mae"], cov, r["n"]))
    out: dict[str, dict[str, dict[str, float]]] = {}
    for mu, by_est in sorted(acc.items(), reverse=True):
        out[mu] = {}
        for est, rows in by_est.items():
            mae, cov, n = (np.array(x, dtype=float) for x in zip(*rows, strict=True))
            out[mu][est] = {
                "mae_deg": float(np.sum(mae * n) / n.sum()),
                "coverage_95": float(np.sum(cov * n) / n.sum()),
                "samples": int(n.sum()),
            }
    return out


def pick(by_est: dict[str, dict[str, float]], suffix: str) -> dict[str, float]:
    return next(v for k, v in by_est.items() if k.endswith(suffix))


def roles(report: Path) -> tuple[str, str]:
    """The rows of the fitted model and of the start it came from (fit_bags_check.py
    scores them in that order): by file where the report maps files to rows, else by
    the stems the labels of two equally named networks carry."""
    summary = json.loads((report / "metrics.json").read_text())
    rows = summary.get("model_estimators")
    if rows is None:  # reports from before the map
        return FITTED, SHIPPED
    fitted, start = summary["models"]
    return rows[fitted], rows[start]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cars", type=Path, nargs="+", required=True, help="car folders")
    p.add_argument("--report", default="new-drives-identified", help="report folder in each")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    folders = {w.name: w for w in sorted(args.cars)}
    table = {name: cells(w / args.report) for name, w in folders.items()}
    args.out.write_text(json.dumps(table, indent=1, ensure_ascii=False) + "\n")
    print("| car | μ | fitted MAE | shipped MAE | UKF (identified) MAE | fitted inside ±1.96 σ "
          "| shipped inside ±1.96 σ |\n|---|---|---|---|---|---|---|")  # fmt: skip
    inside: dict[str, list[float]] = {"fitted": [], "shipped": []}
    for car, by_mu in table.items():
        fitted, start = roles(folders[car] / args.report)
        for mu, by_est in by_mu.items():
            f, s, u = pick(by_est, fitted), pick(by_est, start), by_est["UKF"]
            inside["fitted"].append(f["coverage_95"])
            inside["shipped"].append(s["coverage_95"])
            maes = " | ".join(f"{x['mae_deg']:.4f}" for x in (f, s, u))
            print(f"| {car} | {mu} | {maes} | {f['coverage_95']:.3f} | {s['coverage_95']:.3f} |")
    for name, values in inside.items():
        x = np.array(values)
        band = int(np.sum((x >= 0.93) & (x <= 0.97)))
        print(f"{name}: cells in 93-97 % {band} of {x.size}; min {x.min():.3f}, max {x.max():.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
