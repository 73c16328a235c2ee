"""Per car × μ cell: the share of samples inside a network's published 95 % interval, from
``sideslip-evaluate`` reports of the held-out benchmark (one report folder per car, e.g.
``described_validation.py --held-out``'s ``CAR/report-true``).

Pools the runs of a cell by sample count (``fit_bags_cells.cells``), as
``docs/evaluation/intervals`` does, and counts the cells inside 93–97 %. Prints a
markdown table and writes ``--out`` (JSON).

    python training/scripts/coverage_cells.py \\
        --reports data/described-held-out-ensemble/heldout_*/report-true \\
        --out docs/evaluation/intervals/held-out-ukf-ensemble.json

A report that scored several networks needs ``--model FILE``: the row of that model
file (the report's ``model_estimators`` map); ``{car}`` in FILE stands for the report's
car, for a model of each car's own (``--model 'data/cvheld/{car}-ftcv.safetensors'``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_cells import cells

BAND = (0.93, 0.97)


def network_row(by_est: dict[str, dict[str, float]], label: str | None = None) -> dict[str, float]:
    """The row ``label``, or the one row with a coverage (the network; the baselines
    publish no σ)."""
    if label is not None:
        return by_est[label]
    rows = [v for v in by_est.values() if np.isfinite(v["coverage_95"])]
    if len(rows) != 1:
        raise SystemExit(f"expected one estimator with an interval, found {len(rows)}")
    return rows[0]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--reports", nargs="+", type=Path, required=True,
                   help="report folders, one per car, named CAR/REPORT")  # fmt: skip
    p.add_argument("--out", type=Path)
    p.add_argument(
        "--model",
        help="the model file whose row to read (as given to the report; {car}: the car's name)",
    )
    args = p.parse_args(argv)
    table: dict[str, dict[str, dict[str, float]]] = {}
    for report in sorted(args.reports):
        car = report.parent.name
        label = None
        if args.model is not None:
            label = json.loads((report / "metrics.json").read_text())["model_estimators"][
                args.model.format(car=car)
            ]
        table[car] = {mu: network_row(by_est, label) for mu, by_est in cells(report).items()}
    mus = sorted({mu for row in table.values() for mu in row})
    print("| car | " + " | ".join(f"μ = {mu}" for mu in mus) + " |")
    print("|---|" + "---|" * len(mus))
    inside = n_cells = 0
    cov_sum = samples = 0.0
    for car, row in table.items():
        marks = []
        for mu in mus:
            c = row[mu]["coverage_95"]
            ok = BAND[0] <= c <= BAND[1]
            inside += ok
            n_cells += 1
            cov_sum += c * row[mu]["samples"]
            samples += row[mu]["samples"]
            marks.append(f"**{c:.3f}**" if ok else f"{c:.3f}")
        print(f"| {car.removeprefix('heldout_')} | " + " | ".join(marks) + " |")
    pooled = cov_sum / samples
    print(f"\ncells in 93–97 %: {inside} of {n_cells}; pooled {pooled:.3f}")
    if args.out is not None:
        args.out.write_text(json.dumps(
            {"cells": table, "in_band": inside, "cells_total": n_cells, "pooled": pooled},
            indent=2) + "\n")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
