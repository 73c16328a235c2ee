"""What a ``sideslip-fit --bags`` user ends up running, against what they ran before the
fit, on the car's other drives (``fit_bags_check.py --as-recordings`` folders).

A fit to recordings is run alone by the node's default (``pso_lstm.mirror_average:
auto``); the shipped start it fine-tuned is averaged with its mirror image. Since
2026-12-06 the handover compares them so on the recordings' validation stretch, and a
start that wins comes back as the file (averaged, as before). Per car, on its other
drives (``--drives``), pooled MAE [deg] with the files the node would be given
(description, identified axles, ``--car given``):

- ``deployed``: the fitted file as the node's default runs it;
- ``fitted alone`` / ``fitted averaged``: the same file each way;
- ``start averaged``: the shipped start as the node's default runs it (the user's model
  before the fit); ``start alone``: the start as the earlier figures scored it;

and whether the fit kept the start (``kept_start_weights`` in its ``metrics.json``), the
validation MAE of the start (as scored by the handover) and of the best epoch. Writes
``OUT`` (JSON) and prints a markdown table.

    python training/scripts/fit_bags_handover.py --cars data/fbr-new/fleet2_car00? \
        --drives data/val-benchmark --out FILE.json
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import torch

from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import evaluate_runs, pooled
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_folder import fitted_car, study_parser

START = "fleet_ukf_ensemble"
COLUMNS = ("deployed", "fitted alone", "fitted averaged", "start averaged", "start alone")


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
        row: dict[str, object] = {}
        for names, mirror in ((("deployed", "start averaged"), "auto"),
                              (("fitted alone", "start alone"), "no"),
                              (("fitted averaged", None), "yes")):  # fmt: skip
            models = [(n, *m) for n, m in zip(names, (fitted, start), strict=True) if n]
            traces = evaluate_runs(
                runs,
                models,
                window_steps=fitted[1].window_steps,
                dt_s=fitted[1].dt_s,
                beyond_fit_range="auto",
                mirror_average=mirror,
                **fitted_car(work),
            )
            row |= {name: m.mae for name, m in pooled(traces).items() if name in COLUMNS}
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
