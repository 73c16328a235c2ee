"""Models trained with and without crossfall in their data, per validation car, on level
and banked roads: the choice of whether a model trained on ``--bank-spread`` drives
replaces a shipped one, made without the held-out cars.

Every ``--model`` (shipped names or files) is run as the node runs it (mirror average
as the model records, each bag's own car for the UKF and the car inputs) on every
``--data`` folder (``validation_benchmark.py`` or ``sideslip-generate`` folders with
ground truth); per folder and car the pooled MAE and mean error (the bias a crossfall
leaves) [deg], the mean over cars and the pooled figure. The held-out benchmark's folders are
scored the same way, once, after the choice. ``--start-at F`` cuts every run to its
part from that fraction on, so the filter and the window start in mid-manoeuvre (a
restart after a gap, a recording cut in time).

    python training/scripts/crossfall_training_check.py --model fleet_ukf_paper new.safetensors \
        --data data/val-benchmark data/val-benchmark-bank2.5 --jobs 2 --out FILE.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from sideslip_training import observer
from sideslip_training.dataset import load_runs, slice_samples
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve


def _car(run) -> str:
    vehicle = run.run_metadata.get("vehicle") or {}
    return str(vehicle.get("name") or Path(str(run.bag)).name)


def score(model: str, folder: str, jobs: int, start_at: float = 0.0) -> dict:
    """Per car and overall MAE / mean error [deg] of ``model`` on ``folder``'s runs, each
    from ``start_at`` (a fraction of the run) on."""
    net, meta = load_model(resolve(model))
    w = meta.window_steps
    runs, _ = load_runs([folder], step_s=meta.dt_s)
    if start_at > 0.0:
        runs = [
            dataclasses.replace(
                r, samples=slice_samples(r.samples, int(start_at * len(r.samples)), len(r.samples))
            )
            for r in runs
        ]
    if meta.needs_observer:
        assert meta.observer is not None
        observer.precompute(runs, meta.observer, None, jobs=jobs, progress=False)
    errors: dict[str, list[np.ndarray]] = defaultdict(list)
    for run in runs:
        est = predict_run(net, meta, run, mirror_average="auto")
        err = np.degrees(est - run.samples.beta_rad()[w - 1 :])
        errors[_car(run)].append(err[np.isfinite(err)])
    cars = {}
    for car, parts in sorted(errors.items()):
        e = np.concatenate(parts)
        cars[car] = {"mae_deg": float(np.mean(np.abs(e))), "me_deg": float(np.mean(e)),
                     "samples": int(e.size)}  # fmt: skip
    pooled = np.concatenate([np.concatenate(p) for p in errors.values()])
    return {
        "cars": cars,
        "mean_mae_deg": float(np.mean([c["mae_deg"] for c in cars.values()])),
        "mean_me_deg": float(np.mean([c["me_deg"] for c in cars.values()])),
        "pooled_mae_deg": float(np.mean(np.abs(pooled))),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", nargs="+", required=True, help="shipped names or .safetensors")
    p.add_argument("--data", nargs="+", required=True, help="folders of bags with ground truth")
    p.add_argument("--jobs", type=int, default=1, help="processes for the UKF observer")
    p.add_argument("--start-at", type=float, default=0.0, help="fraction of each run [0, 1)")
    p.add_argument("--out", type=Path, required=True, help="JSON report")
    args = p.parse_args(argv)
    if not 0.0 <= args.start_at < 1.0:
        p.error(f"--start-at must be in [0, 1), got {args.start_at}")
    report: dict[str, dict] = {}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    for model in args.model:
        for folder in args.data:
            got = score(model, folder, args.jobs, args.start_at)
            report.setdefault(model, {})[folder] = got
            print(f"{model:45s} {folder:32s} mean MAE {got['mean_mae_deg']:.4f}  "
                  f"pooled {got['pooled_mae_deg']:.4f}  mean ME {got['mean_me_deg']:+.4f}",
                  flush=True)  # fmt: skip
            # After every folder: a long run stopped part way keeps what it scored.
            args.out.write_text(json.dumps(report, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
