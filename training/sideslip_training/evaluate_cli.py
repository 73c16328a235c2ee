"""``sideslip-evaluate``: score models beside the baselines on bags with ground truth.

The house CLI pattern: ``--help`` reads like a manual, ``--out`` never overwritten
without ``--force``, bad input one line on stderr and exit 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from sideslip_msgs_py.artifact import ArtifactError
from sideslip_msgs_py.topic_map import TopicMap, TopicMapError
from sideslip_msgs_py.vehicle_description import VehicleDescription, VehicleDescriptionError

from .cli_errors import EXIT_BAD_INPUT, CliError
from .config import DT_S, WINDOW_STEPS
from .dataset import DatasetError, load_runs
from .export import load_model
from .init_model import InitError, resolve
from .inputs import add_car_files_arguments, add_mirror_average_argument


def _evaluate_parser() -> argparse.ArgumentParser:
    from sideslip_estimator.backends.model_files import BEYOND_FIT_RANGE

    p = argparse.ArgumentParser(
        prog="sideslip-evaluate",
        description=(
            "Score exported models beside the baselines (β = 0, the kinematic atan2(Y_v, "
            "X_v) raw and smoothed, and with --single-track-params / --ukf-params the "
            "physics filters) on bags with ground truth: MAE, ME, RMSE, R² in degrees per "
            "bag (scenario) in the paper's Table 5/6 layout, the mean over bags and the "
            "pooled figure over all samples, β traces and error PDFs. Without --model: "
            "the baselines only."
        ),
    )
    p.add_argument(
        "--model",
        nargs="*",
        default=[],
        type=Path,
        metavar="FILE",
        help="model files (.safetensors) or names of shipped models",
    )
    p.add_argument("--data", nargs="+", required=True, metavar="DIR")
    p.add_argument("--out", type=Path, help="report folder: table.md, table.csv, figures")
    p.add_argument(
        "--topic-map",
        type=Path,
        metavar="FILE",
        help="read bags recorded with other topics/types through this map (YAML: topic and "
        "field of each channel and of the reference β or velocity; docs/topic-maps.md)",
    )
    p.add_argument("--force", action="store_true", help="write into an existing --out")
    p.add_argument("--smoothing", type=int, default=20, help="smoothed baseline: samples averaged")
    p.add_argument("--title", default="", help="heading of the markdown table")
    p.add_argument(
        "--beyond-fit-range",
        choices=list(BEYOND_FIT_RANGE),
        default="auto",
        help="a model fine-tuned on one car's recordings (sideslip-fit --bags), while its "
        "window reaches beyond their range: start: the shipped model it started from "
        "(estimate and σ); model: its own, σ widened; auto (default, as the node): start "
        "when the recordings stayed under 5 m/s² and that model is shipped with the same "
        "training data",
    )
    add_mirror_average_argument(p, "every model (and start model)")
    add_car_files_arguments(p)
    p.add_argument(
        "--single-track-params",
        metavar="FILE",
        help="score the single-track Kalman filter with these parameters (a shipped name or "
        "a YAML from python -m sideslip_sim.single_track VEHICLE)",
    )
    p.add_argument(
        "--ukf-params",
        metavar="FILE",
        help="score the UKF with these parameters (a shipped name or a YAML from python -m "
        "sideslip_sim.ukf_params VEHICLE)",
    )
    p.add_argument(
        "--window-steps",
        type=int,
        default=WINDOW_STEPS,
        help="without --model: the window whose first samples are not scored (default 100)",
    )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    from .evaluate import (
        StartModelError,
        evaluate_runs,
        metrics_json,
        model_label,
        outside_training_cars,
        pooled,
    )
    from .evaluate_figures import plot_band, plot_error_pdfs, plot_traces
    from .evaluate_tables import table_csv, table_markdown
    from .filter_replay import FilterError

    args = _evaluate_parser().parse_args(argv)
    try:
        if (
            args.out is not None
            and args.out.exists()
            and any(args.out.iterdir())
            and not args.force
        ):
            raise CliError(f"--out {args.out} is not empty; pass --force")
        if args.smoothing < 1:
            raise CliError(f"--smoothing must be >= 1, got {args.smoothing}")
        models = []
        # A path, or the name of a shipped model (as sideslip-calibrate and --init take).
        args.model = [resolve(spec, "--model") for spec in args.model]
        for path in args.model:
            net, meta = load_model(path)
            models.append((model_label(meta), net, meta))
        names = [m[0] for m in models]
        if len(set(names)) != len(names):  # two LSTMs: tell them apart by file
            stems = [p.stem for p in args.model]
            tags = stems if len(set(stems)) == len(stems) else [p.parent.name for p in args.model]
            if len(set(tags)) != len(tags):  # same stems in same-named folders
                tags = [str(p) for p in args.model]
            if len(set(tags)) != len(tags):
                raise CliError("--model names one file twice")
            models = [
                (f"{n} ({tag})", net, meta)
                for (n, net, meta), tag in zip(models, tags, strict=True)
            ]
        windows = {meta.window_steps for _, _, meta in models} or {args.window_steps}
        if len(windows) != 1:
            raise CliError(f"models have different window lengths: {sorted(windows)}")
        if min(windows) < 1:
            raise CliError(f"--window-steps must be >= 1, got {args.window_steps}")
        steps = {meta.dt_s for _, _, meta in models} or {DT_S}
        if len(steps) != 1:
            rates = ", ".join(f"{1 / s:g} Hz" for s in sorted(steps))
            raise CliError(f"models run at different rates ({rates}): score them separately")
        # Bags at another rate are resampled to the models' step (or refused), never
        # scored at the wrong rate; the report printed below says which.
        topic_map = TopicMap.load(args.topic_map) if args.topic_map else None
        runs, report = load_runs(args.data, step_s=steps.pop(), topic_map=topic_map)
        print(str(report), file=sys.stderr)
        window = next(iter(windows))
        short = [r.name for r in runs if len(r.samples) < window]
        if short:
            print(f"skipped (shorter than {window} samples): {', '.join(short)}", file=sys.stderr)
            runs = [r for r in runs if len(r.samples) >= window]
        if not runs:
            raise CliError(f"no run of {args.data} holds a full window of {window} samples")
        observer_file = str(args.observer_params) if args.observer_params else None
        if args.car == "given" and not (args.vehicle or args.observer_params):
            raise CliError("--car given needs --vehicle and/or --observer-params")
        for label, _, meta in models:
            outside = {
                r.name: outside_training_cars(meta, r, observer_file, args.car) for r in runs
            }
            if any(outside.values()):
                lines = sorted({line for found in outside.values() for line in found})
                print(
                    f"{label}: the car of {sum(map(bool, outside.values()))} run(s) lies "
                    f"outside its training cars ({'; '.join(lines)}): scored as the estimator "
                    "publishes it with outside_fleet auto (a residual on the UKF: the UKF alone)",
                    file=sys.stderr,
                )
    except (CliError, ArtifactError, DatasetError, InitError, OSError, TopicMapError) as err:
        print(f"sideslip-evaluate: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    filters = {
        name: params
        for name, params in (
            ("single_track", args.single_track_params),
            ("ukf", args.ukf_params),
        )
        if params
    }
    try:
        traces = evaluate_runs(
            runs,
            models,
            window_steps=windows.pop(),
            smoothing_steps=args.smoothing,
            vehicle=VehicleDescription.load(args.vehicle) if args.vehicle else None,
            observer_params_file=observer_file,
            car=args.car,
            filters=filters,
            beyond_fit_range=args.beyond_fit_range,
            mirror_average=args.mirror_average,
        )
    except (DatasetError, VehicleDescriptionError, FilterError, StartModelError) as err:
        print(f"sideslip-evaluate: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    md = table_markdown(traces, args.title)
    print(md)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "table.md").write_text(md)
        (args.out / "table.csv").write_text(table_csv(traces))
        plot_traces(traces, args.out)
        plot_error_pdfs(traces, args.out)
        for i, t in enumerate(tr for tr in traces if tr.sigma_rad is not None):
            plot_band(t, args.out / f"band_{t.scenario}_{i}.png")

        summary = {
            "models": [str(p) for p in args.model],
            # Which estimator row is which file: a label carries the file's stem only
            # where two models' labels would collide.
            "model_estimators": {
                str(p): name for p, (name, _, _) in zip(args.model, models, strict=True)
            },
            "data": args.data,
            "smoothing_steps": args.smoothing,
            "filters": filters,
            "results": [
                {
                    "scenario": t.scenario,
                    "estimator": t.estimator,
                    **metrics_json(t.metrics),
                    **({} if t.sigma_rad is None else {"coverage_95": t.coverage}),
                }
                for t in traces
            ],
            "pooled": [{"estimator": n, **metrics_json(m)} for n, m in pooled(traces).items()],
        }
        (args.out / "metrics.json").write_text(
            json.dumps(summary, indent=2, allow_nan=False) + "\n"
        )
    return 0
