"""How a model anchored on the UKF degrades when it is given the wrong car.

Scores a model that reads the UKF observer on the held-out runs with every run's
``ukf`` params file replaced by one car's (default ``paper_sedan``): the situation of
a user who leaves ``pso_lstm.observer_params_file`` at another car's file. Prints the
mean run MAE, that of the 20-step smoothed kinematic baseline, and on how many runs the
model is worse than it.

    python training/scripts/observer_wrong_car.py \
        sideslip_estimator/sideslip_estimator/data/models/fleet_ukf_paper.safetensors \
        --data data/held-out
"""

from __future__ import annotations

import argparse
from importlib import resources

import numpy as np

from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import kinematic, predict_run
from sideslip_training.export import load_model
from sideslip_training.inputs import add_mirror_average_argument


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model")
    p.add_argument("--data", default="data/held-out")
    p.add_argument("--car", default="paper_sedan", help="shipped ukf params file to give")
    add_mirror_average_argument(p, "the network")
    args = p.parse_args()
    ref = resources.files("sideslip_estimator").joinpath(f"data/ukf/{args.car}.yaml")
    net, meta = load_model(args.model)
    runs, _ = load_runs([args.data])
    model_mae, base_mae = [], []
    with resources.as_file(ref) as wrong_file:
        for run in runs:
            # car="given": the given file for every run, though the bags record their
            # own car (as a node left with another car's observer_params_file).
            est = predict_run(
                net,
                meta,
                run,
                observer_params_file=str(wrong_file),
                car="given",
                mirror_average=args.mirror_average,
            )
            base = kinematic(run, 20, meta.window_steps)
            truth = run.samples.beta_rad()[meta.window_steps - 1 :]
            ok = np.isfinite(est) & np.isfinite(base)
            model_mae.append(np.degrees(np.abs(est[ok] - truth[ok])).mean())
            base_mae.append(np.degrees(np.abs(base[ok] - truth[ok])).mean())
    ratio = np.array(model_mae) / np.array(base_mae)
    print(
        f"{args.model} with {args.car}'s ukf file on {len(runs)} runs "
        f"(mirror average {args.mirror_average}): mean run MAE "
        f"{np.mean(model_mae):.3f} deg (20-step kinematic {np.mean(base_mae):.3f}); worse "
        f"than it on {int(np.sum(ratio > 1))} runs, worst ratio {ratio.max():.2f}"
    )


if __name__ == "__main__":
    main()
