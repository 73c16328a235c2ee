"""What a ``sideslip-fit --bags`` user ends up running, against what they ran before the
fit, on the car's other drives (``fit_bags_check.py --as-recordings`` folders).

A fit to recordings is run alone by the node's default (``pso_lstm.mirror_average:
auto``); the shipped start it fine-tuned is averaged with its mirror image. Since
2026-12-06 the handover asks the fit to beat the start on the recordings' validation
stretch both alone and averaged, and a start that wins comes back as the file
(averaged, as before). Per car, on its other
drives (``--drives``) **and on each drive's mirror image** (the same drive the other way
round: the drives as generated start to the side the training drives did, which favours
a network alone; docs/evaluation/direction), pooled MAE [deg] over both, with the files
the node would be given (description, identified axles, ``--car given``):

- ``deployed``: the fitted file as the node's default runs it;
- ``fitted alone`` / ``fitted averaged``: the same file each way;
- ``start averaged``: the shipped start as the node's default runs it (the user's model
  before the fit); ``start alone``: the start as the earlier figures scored it;
- ``... one way``: the same on the drives as generated only;

and whether the fit kept the start (``kept_start_weights`` in its ``metrics.json``), the
validation MAE of the start (as scored by the handover) and of the best epoch. The
averaged estimate of a drive is half the difference of the network alone on the drive
and on its mirror image (exactly what the node computes, the filters being symmetric),
so each network runs once per direction. Writes ``OUT`` (JSON), prints a markdown table.

    python training/scripts/fit_bags_handover.py --cars data/fbr-new/fleet2_car00? \
        --drives data/val-benchmark --out FILE.json
"""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from sideslip_msgs_py.data_source import mirror_average_on
from sideslip_msgs_py.mirror import mirrored
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import Trace, evaluate_runs
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve
from sideslip_training.training_data import MIRROR_SUFFIX

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_folder import fitted_car, study_parser

START = "fleet_ukf_ensemble"
COLUMNS = (
    "deployed",
    "fitted alone",
    "fitted averaged",
    "start averaged",
    "start alone",
    "fitted alone one way",
    "start alone one way",
)


def maes(traces: list[Trace], name: str) -> dict[str, float]:
    """``name``'s MAE [deg] alone and averaged with its mirror image, over the drives and
    their mirror images, and over the drives alone (``... one way``)."""
    mine = {t.scenario: t for t in traces if t.estimator == name}
    alone_err, alone_one, averaged_err = [], [], []
    for scenario, here in mine.items():
        if scenario.endswith(MIRROR_SUFFIX):
            continue
        there = mine[scenario + MIRROR_SUFFIX]
        err = here.estimate_rad - here.reference_rad
        alone_err += [err, there.estimate_rad - there.reference_rad]
        alone_one.append(err)
        # On the mirror image the averaged estimate is the negation: the same |error|.
        averaged_err.append(0.5 * (here.estimate_rad - there.estimate_rad) - here.reference_rad)

    def mae(parts: list[np.ndarray]) -> float:
        e = np.concatenate(parts)
        return float(np.degrees(np.mean(np.abs(e[np.isfinite(e)]))))

    return {
        f"{name} alone": mae(alone_err),
        f"{name} averaged": mae(averaged_err),
        f"{name} alone one way": mae(alone_one),
    }


def main(argv: list[str] | None = None) -> int:
    p = study_parser(__doc__)
    p.add_argument("--drive-glob", default="{car}_*", help="the car's drives in --drives")
    p.add_argument("--start", default=START, help="the start model the fits fine-tuned")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    start = load_model(resolve(args.start))
    summary: dict[str, dict[str, object]] = {}
    for work in args.cars:
        fitted = load_model(work / "fitted.safetensors")
        drives = sorted(args.drives.glob(args.drive_glob.format(car=work.name)))
        if not drives:
            raise SystemExit(f"{work.name}: no drives in {args.drives}")
        runs, _ = load_runs(drives, step_s=fitted[1].dt_s)
        both = [*runs, *(replace(r, name=r.name + MIRROR_SUFFIX, samples=mirrored(r.samples))
                         for r in runs)]  # fmt: skip
        traces = evaluate_runs(
            both,
            [("fitted", *fitted), ("start", *start)],
            window_steps=fitted[1].window_steps,
            dt_s=fitted[1].dt_s,
            beyond_fit_range="auto",
            mirror_average=False,
            **fitted_car(work),
        )
        row = {**maes(traces, "fitted"), **maes(traces, "start")}
        deployed = mirror_average_on("auto", fitted[1].provenance)
        row["deployed"] = row["fitted averaged" if deployed else "fitted alone"]
        run_dir = work / "fitted.fit" / "train-run"
        metrics = json.loads((run_dir / "metrics.json").read_text())
        history = json.loads((run_dir / "history.json").read_text())
        row |= {
            "kept_start": bool(metrics.get("kept_start_weights")),
            "recordings": fitted[1].provenance.get("recordings"),
            "validation_mirror_averaged": metrics.get("validation_mirror_averaged"),
            "val_start": history["start_val_mae_deg"],
            "val_best_epoch": min(r["val_mae_deg"] for r in history["history"]),
            "best_epoch": history["best_epoch"],
        }
        summary[work.name] = row
        print(work.name, json.dumps(row), flush=True)
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    print("| car | kept the start | validation: start / best epoch | " + " | ".join(COLUMNS) + " |")
    print("|---|---|---|" + "---|" * len(COLUMNS))
    for car, r in summary.items():
        cells = " | ".join(f"{r[c]:.4f}" for c in COLUMNS)
        kept = "yes" if r["kept_start"] else "no"
        print(f"| {car} | {kept} | {r['val_start']:.4f} / {r['val_best_epoch']:.4f} | {cells} |")
    means = [float(np.mean([r[c] for r in summary.values()])) for c in COLUMNS]
    print("| mean | | | " + " | ".join(f"{m:.4f}" for m in means) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
