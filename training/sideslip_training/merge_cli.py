"""``sideslip-merge``: average several trained networks into one model file
(:mod:`.merge`), score it beside its members on validation bags, and give it a σ
calibrated there (as ``sideslip-calibrate``).

    sideslip-merge fleet_ukf_measurable fleet_ukf_described --data data/fleet-val \\
        --out merged.safetensors
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from sideslip_msgs_py.artifact import ArtifactError
from sideslip_msgs_py.data_source import RECORDINGS_KEY, mirror_average_on
from sideslip_msgs_py.topic_map import TopicMap, TopicMapError
from sideslip_msgs_py.vehicle_description import VehicleDescription, VehicleDescriptionError

from .calibrate import Errors, calibrate, described_kinds
from .cli_errors import EXIT_BAD_INPUT
from .dataset import DatasetError, load_runs
from .export import export_model, load_model
from .init_model import InitError, resolve
from .inputs import add_car_files_arguments, add_mirror_average_argument
from .merge import MergeError, merge


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="sideslip-merge",
        description=(
            "Average two or more models that read the same inputs into one model file "
            "(one wider LSTM: the estimator runs it as any model), scored beside its "
            "members on validation bags (never test ones) and given a σ calibrated there."
        ),
    )
    p.add_argument("models", nargs="+", metavar="MODEL", help=".safetensors files or shipped names")
    p.add_argument("--data", nargs="+", required=True, metavar="DIR", help="validation bags")
    p.add_argument("--out", required=True, type=Path, metavar="FILE.safetensors")
    p.add_argument(
        "--shares", type=float, nargs="+", help="each model's share of β̂ (default: equal; sum 1)"
    )
    p.add_argument("--coverage", type=float, default=0.95, help="σ: share inside ±z·σ (0.95)")
    p.add_argument("--seed", type=int, default=0, help="σ: which bags fit and which scale")
    p.add_argument("--topic-map", type=Path, metavar="FILE", help="see sideslip-train")
    add_car_files_arguments(p)
    add_mirror_average_argument(p, "score the members and calibrate the merged model's σ on each")
    p.add_argument("--force", action="store_true", help="replace --out")
    p.epilog = (
        "For models that read the UKF the σ is calibrated with the runs' car files: true "
        "or identified ones, or a mix with described ones (--car mixed); described files "
        "alone are refused, since that σ would be the model's own (sideslip-calibrate "
        "--car described adds one for them afterwards)."
    )
    return p


def _mae_rmse_me(errors: Errors) -> tuple[float, float, float]:
    err = np.degrees(errors.err)
    return float(np.mean(np.abs(err))), float(np.sqrt(np.mean(err**2))), float(np.mean(err))


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.out.exists() and not args.force:
            raise DatasetError(f"--out {args.out} exists; pass --force")
        if args.car == "given" and not (args.vehicle or args.observer_params):
            raise DatasetError("--car given needs --vehicle and/or --observer-params")
        members = [load_model(resolve(m, "MODEL")) for m in args.models]
        net, meta = merge(members, args.models, args.shares)
        topic_map = TopicMap.load(args.topic_map) if args.topic_map else None
        runs, report = load_runs(args.data, step_s=meta.dt_s, topic_map=topic_map)
        print(str(report), file=sys.stderr)
        car = {
            "vehicle": VehicleDescription.load(args.vehicle) if args.vehicle else None,
            "observer_params_file": str(args.observer_params) if args.observer_params else None,
            "car": args.car,
        }
        if described_kinds(runs, meta, car) == {True}:
            # The merged model's σ is its own, published with every other kind of file;
            # one calibrated with guessed tyres alone would be too wide there.
            raise DatasetError(
                "every run's UKF file was made from a description (axles_from: "
                "description): the merged model's own σ is calibrated with true or "
                "identified car files (or a mix); give those, then add the σ for "
                "described files with sideslip-calibrate --car described"
            )
        scores = {}
        for name, (m_net, m_meta) in zip(args.models, members, strict=True):
            mirror = mirror_average_on(args.mirror_average, m_meta.provenance)
            errors = Errors.of_runs(runs, m_net, m_meta, **car, mirror_average=mirror)
            scores[name] = _mae_rmse_me(errors)
        # Scored and σ fitted on the estimate the node publishes with the same setting
        # (the merged file records its members' recordings: auto goes by their sum).
        mirror = mirror_average_on(args.mirror_average, meta.provenance)
        car = {**car, "mirror_average": mirror}
        errors = Errors.of_runs(runs, net, meta, **car)
        mae, rmse, me = _mae_rmse_me(errors)
        unc, figures = calibrate(
            runs, net, meta, coverage=args.coverage, seed=args.seed, car=car, errors=errors
        )
        figures = {**figures, "mirror_averaged": float(mirror)}
    except (
        DatasetError,
        ArtifactError,
        InitError,
        MergeError,
        TopicMapError,
        OSError,
        VehicleDescriptionError,
    ) as err:
        print(f"sideslip-merge: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    members_meta = [
        {
            **entry,
            "data_mae_deg": scores[entry["file"]][0],
            "data_rmse_deg": scores[entry["file"]][1],
        }
        for entry in meta.provenance["merged"]
    ]
    out_meta = replace(
        meta,
        uncertainty=unc.to_dict(),
        metrics={
            "val_mae_deg": mae,
            "val_rmse_deg": rmse,
            "val_me_deg": me,
            "interval_calibration": figures,
        },
        provenance={
            "merged": members_meta,
            **{k: v for k, v in meta.provenance.items() if k == RECORDINGS_KEY},
            "scored_and_calibrated_on": [str(d) for d in args.data],
            "command": "sideslip-merge " + " ".join(sys.argv[1:] if argv is None else argv),
        },
    )
    export_model(args.out, net, out_meta, force=args.force)
    for name, (m_mae, m_rmse, _) in scores.items():
        print(f"{name}: MAE {m_mae:.4f} deg, RMSE {m_rmse:.4f} deg on --data")
    print(
        f"wrote {args.out} ({meta.hidden_units} units): MAE {mae:.4f} deg, RMSE {rmse:.4f} deg "
        f"on --data; σ scale {unc.scale:.3f}, {figures['coverage_scale_half']:.3f} of the "
        f"scale half inside"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
