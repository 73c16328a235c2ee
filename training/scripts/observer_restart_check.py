"""What a UKF observer started again at every cut in time costs: a model on each of a
car's runs whole (one filter through the run, as the node runs it) and cut into K
consecutive blocks, each filtered from its own first sample, as every split in time and
every ``--folds`` block was until 2026-12-07. Both are scored on the same samples (each
block's from its first full window on); mirror-averaged where that is the model's
default. Writes JSON to stdout.

    python training/scripts/observer_restart_check.py data/fbc-folds/fleet2_car001 --blocks 5

The folder is a ``fit_bags_check.py`` car folder: ``own/`` (the runs), ``description.yaml``
and ``fitted.ukf.yaml`` (the identified axles, the files the node is given).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import torch

from sideslip_training.dataset import load_runs, slice_samples
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_folder import fitted_car


def mae_deg(errors: list[np.ndarray]) -> float:
    return float(np.degrees(np.mean(np.abs(np.concatenate(errors))))) if errors else float("nan")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("car", type=Path, help="a fit_bags_check.py car folder")
    p.add_argument("--blocks", type=int, default=5)
    p.add_argument("--model", default="fleet_ukf_ensemble")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    net, meta = load_model(resolve(args.model))
    car = fitted_car(args.car)
    runs, _ = load_runs([args.car / "own"], step_s=meta.dt_s)
    w = meta.window_steps
    through: list[list[np.ndarray]] = [[] for _ in range(args.blocks)]
    restarted: list[list[np.ndarray]] = [[] for _ in range(args.blocks)]
    for run in runs:
        n, truth = len(run.samples), run.samples.beta_rad()
        whole = np.full(n, np.nan)
        whole[w - 1 :] = predict_run(net, meta, run, mirror_average="auto", **car) - truth[w - 1 :]
        cuts = np.linspace(0, n, args.blocks + 1).astype(int)
        for k in range(args.blocks):
            a, b = cuts[k], cuts[k + 1]
            if b - a < w:
                continue
            # A block as a run of its own with no recording: the filter starts at its start.
            block = dataclasses.replace(run, samples=slice_samples(run.samples, a, b))
            again = (
                predict_run(net, meta, block, mirror_average="auto", **car) - truth[a + w - 1 : b]
            )
            kept = np.isfinite(again) & np.isfinite(whole[a + w - 1 : b])
            restarted[k].append(again[kept])
            through[k].append(whole[a + w - 1 : b][kept])
    flat = lambda xs: [e for block in xs for e in block]  # noqa: E731
    out = {
        "car": args.car.name,
        "model": args.model,
        "blocks": args.blocks,
        "runs": len(runs),
        "same_samples_filter_through_mae_deg": mae_deg(flat(through)),
        "same_samples_filter_restarted_mae_deg": mae_deg(flat(restarted)),
        "per_block_filter_through_mae_deg": [mae_deg(x) for x in through],
        "per_block_filter_restarted_mae_deg": [mae_deg(x) for x in restarted],
    }
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
