"""A car's own recordings set the σ's scale: coverage of the 95 % interval with the
fleet's calibration against one rescaled on the car's own labelled driving.

``sideslip-calibrate --scale-only`` keeps the σ terms ``fleet_ukf_measurable`` was
calibrated with on the validation fleet and fits only their scale on one car's own
recordings (given the car's description and its identified ``ukf`` file, as the node
runs it); the model itself is not trained on them. For each car folder (a description,
its identified ``ukf`` file and its own bags, as ``fit_bags_check.py`` or
``held_out_fit.py --identify`` leave them), both σ are scored on other drives of the
car (``--drives``: bags whose names start with the car's name), per run and pooled.

    python training/scripts/interval_per_car.py --cars data/fit-bags-check/fleet2_car000 \
        --own own --ukf fitted.ukf.yaml --drives data/fleet-val
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from sideslip_training.calibrate import main as calibrate_main
from sideslip_training.evaluate_cli import main as evaluate_main
from sideslip_training.init_model import resolve

MODEL = "fleet_ukf_measurable"


def coverage(report: Path) -> dict[str, dict[str, tuple[float, int]]]:
    """Per estimator: per run (coverage, samples)."""
    out: dict[str, dict[str, tuple[float, int]]] = {}
    for r in json.loads((report / "metrics.json").read_text())["results"]:
        if "coverage_95" in r:
            out.setdefault(r["estimator"], {})[r["scenario"]] = (r["coverage_95"], r["n"])
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cars", type=Path, nargs="+", required=True, help="car folders")
    p.add_argument("--own", default="own", help="the own bags' folder in a car folder")
    p.add_argument("--ukf", default="fitted.ukf.yaml", help="the identified file's name")
    p.add_argument("--drives", type=Path, required=True, help="folder of the cars' other bags")
    p.add_argument("--out", type=Path, required=True, help="summary JSON")
    args = p.parse_args(argv)
    summary = {}
    for work in args.cars:
        name = work.name
        desc, ukf = work / "description.yaml", work / args.ukf
        files = ["--vehicle", str(desc), "--observer-params", str(ukf), "--car", "given"]
        cal = work / "own-scale.safetensors"
        code = calibrate_main(["--model", MODEL, "--data", str(work / args.own), "--out",
                               str(cal), "--scale-only", "--force", *files])  # fmt: skip
        if code:
            return code
        drives = sorted(str(b) for b in args.drives.glob(f"{name}_*"))
        report = work / "interval-report"
        code = evaluate_main(["--model", str(resolve(MODEL)), str(cal), "--data", *drives,
                              "--out", str(report), "--force", *files])  # fmt: skip
        if code:
            return code
        summary[name] = coverage(report)
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    for name, by_est in summary.items():
        for est, runs in by_est.items():
            n = sum(k for _, k in runs.values())
            pooled = sum(c * k for c, k in runs.values()) / n
            cells = " ".join(f"{c:.3f}" for c, _ in runs.values())
            print(f"{name} | {est[-30:]} | pooled {pooled:.3f} | runs {cells}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
