"""``sideslip-identify-axles``: the UKF's axle curves from a car's own labelled bags.

A described car's ``ukf`` file carries the fleet's typical tyres; the car's recordings
with a reference β (an INS, an optical sensor; through ``--topic-map`` for any stack's
topics) measure each axle's force against its slip angle, and with them its cornering
stiffness (:mod:`sideslip_sim.axle_identification`). The tool starts from the
description's file (``--vehicle``) or any ``ukf`` file (``--start``), fits each axle's
Magic Formula B to the bags and writes the file the estimator's ``ukf`` back-end and the
``measurable`` models read (``ukf.params_file``, ``--observer-params``).

    sideslip-identify-axles --vehicle my_car.yaml --data bags/ --out my_car.ukf.yaml
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sideslip_msgs_py.topic_map import TopicMap, TopicMapError

from .cli_errors import EXIT_BAD_INPUT, CliError
from .dataset import DatasetError, Run, load_runs

CHANNELS = ("x_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m")
"""The channels the identification reads besides the reference β."""


def recorded_runs(runs: Sequence[Run]) -> list[Any]:
    """Each run's finite stretches as :class:`~sideslip_sim.axle_identification.
    RecordedRun` (a NaN in a channel or the reference ends a stretch: the zero-phase
    filter must not run across it)."""
    from sideslip_sim.axle_identification import RecordedRun

    out = []
    for run in runs:
        s = run.samples
        beta = s.beta_rad()
        cols = [getattr(s, c) for c in CHANNELS]
        ok = np.isfinite(beta)
        for c in cols:
            ok &= np.isfinite(c)
        # Stretches of consecutive finite rows.
        edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
        t = (s.stamp_ns - s.stamp_ns[0]) * 1e-9
        for k, (start, stop) in enumerate(zip(edges[::2], edges[1::2], strict=True)):
            sl = slice(start, stop)
            name = run.name if len(edges) == 2 else f"{run.name}~{k}"
            x_v, x_a, y_a, r, stl = (c[sl] for c in cols)
            out.append(RecordedRun(name, t[sl], x_v, beta[sl], r, y_a, x_a, stl))
    return out


def _start_params(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    """The ``ukf`` params to start from and a line saying where they came from."""
    if args.start is not None:
        from sideslip_estimator.backends.base import BackendError
        from sideslip_estimator.backends.params_file import read_params_file
        from sideslip_estimator.backends.ukf_model import SHIPPED_DIR, UkfParams

        try:
            # A path, or the name of a shipped file (as ukf.params_file takes it).
            data, where = read_params_file("ukf", args.start, SHIPPED_DIR)
            UkfParams.from_mapping(data, where)
        except BackendError as err:
            raise CliError(f"--start: {err}") from None
        return dict(data), f"the ukf file {where}"  # type: ignore[call-overload]
    return description_start(Path(args.vehicle))


def description_start(path: Path) -> tuple[dict[str, Any], str]:
    """The ``ukf`` params of the car a description (``sideslip-fit --vehicle``) stands
    for, and a line saying so."""
    from sideslip_sim.vehicle import vehicle_record

    from .car_description import Description
    from .physics_params import nominal_parameters

    desc = Description.load(path)
    params = nominal_parameters("ukf", vehicle_record(desc.vehicle()))
    return params, f"the description {path} (the fleet's typical tyres)"


def identified_file_text(found: Any, recordings: int, source: str, fallback_name: str) -> str:
    """The ukf params file of an :class:`~sideslip_sim.axle_identification.Identification`,
    with a header saying where it came from and what changed."""
    lines = [
        f"# ukf parameters of {found.params.get('name', fallback_name)}: axle B identified "
        f"from {recordings} recording(s) by sideslip-identify-axles,",
        f"# starting from {source}.",
        f"# Cornering stiffness over the start's: front {found.stiffness_ratio_front:.3f}, "
        f"rear {found.stiffness_ratio_rear:.3f}; {found.points} points, residual RMS "
        f"{found.rms_front:.3f} / {found.rms_rear:.3f} of the axle load.",
    ]
    params = {**found.params, "axles_from": "recordings"}
    return "\n".join(lines) + "\n" + yaml.safe_dump(params, sort_keys=False)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="sideslip-identify-axles",
        description="Fit the UKF's axle cornering stiffness (Magic Formula B per axle) to "
        "a car's recordings with a reference β, starting from its description or a ukf "
        "file, and write the ukf params file (sideslip_sim.axle_identification).",
        epilog="The bags need the car's speed, accelerations, yaw rate, steering rack "
        "travel and a reference β or lateral velocity; a few minutes of mixed driving with "
        "some cornering (quasi-steady stretches are what the fit uses). The rest of the "
        "file (mass, inertia, geometry, the curves' shape and peak, relaxation lengths) is "
        "kept from the start.",
    )
    p.add_argument("--data", nargs="+", required=True, help="bags or folders of bags")
    start = p.add_mutually_exclusive_group(required=True)
    start.add_argument(
        "--vehicle",
        help="the car's short description (YAML; sideslip-fit's --vehicle): start from "
        "its described car",
    )
    start.add_argument("--start", help="a ukf params file to start from (a path or a shipped name)")
    p.add_argument("--out", type=Path, required=True, help="the ukf params file to write")
    p.add_argument("--force", action="store_true", help="replace --out")
    p.add_argument("--topic-map", help="read bags recorded with other topics (YAML)")
    p.add_argument(
        "--cutoff-hz",
        type=float,
        default=None,
        help="low-pass corner of the zero-phase filter [Hz] (default: the module's)",
    )
    p.add_argument(
        "--max-yaw-accel",
        type=float,
        default=None,
        help="use samples with |yaw acceleration| up to this [rad/s²] (quasi-steady "
        "driving; default: the module's)",
    )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    from sideslip_sim.axle_identification import (
        IdentificationError,
        IdentificationSettings,
        identify_axles,
    )

    args = _parser().parse_args(argv)
    try:
        if args.out.exists() and not args.force:
            raise CliError(f"--out {args.out} exists; pass --force to replace it")
        settings = IdentificationSettings()
        changes = {}
        if args.cutoff_hz is not None:
            if not (args.cutoff_hz > 0 and math.isfinite(args.cutoff_hz)):
                raise CliError(f"--cutoff-hz must be a positive number, got {args.cutoff_hz}")
            changes["cutoff_hz"] = args.cutoff_hz
        if args.max_yaw_accel is not None:
            if not args.max_yaw_accel > 0:
                raise CliError(f"--max-yaw-accel must be positive, got {args.max_yaw_accel}")
            changes["max_yaw_accel_radps2"] = args.max_yaw_accel
        if changes:
            from dataclasses import replace

            settings = replace(settings, **changes)
        start, source = _start_params(args)
        topic_map = TopicMap.load(args.topic_map) if args.topic_map else None
        runs, report = load_runs(args.data, channels=CHANNELS, topic_map=topic_map)
        print(str(report), file=sys.stderr)
        found = identify_axles(recorded_runs(runs), start, settings)
    except (CliError, DatasetError, TopicMapError, IdentificationError, OSError) as err:
        print(f"sideslip-identify-axles: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    friction = sorted(found.run_friction.values())
    text = identified_file_text(found, len(runs), source, args.out.stem)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    print(
        f"wrote {args.out}: cornering stiffness front ×{found.stiffness_ratio_front:.3f}, "
        f"rear ×{found.stiffness_ratio_rear:.3f} of the start's, from {found.points} points "
        f"of {len(found.run_friction)} stretch(es); road friction fitted per stretch "
        f"{friction[0]:.2f}-{friction[-1]:.2f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
