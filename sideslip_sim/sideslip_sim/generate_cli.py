"""``sideslip-generate``: simulate a preset and write one labelled bag per run
(:func:`sideslip_sim.generate.generate`), with a summary table."""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from sideslip_sim.generate import (
    EXIT_BAD_INPUT,
    EXIT_RUN_FAILED,
    INDEX_FILE,
    SPIN_BETA_DEG,
    OutputDirError,
    RunSummary,
    generate,
    prepare_output,
    single_vehicle,
)
from sideslip_sim.held_out import is_held_out
from sideslip_sim.imu_mounting import ImuMounting
from sideslip_sim.maneuvers import ManeuverError
from sideslip_sim.presets import (
    PRESETS,
    TRAINING_PRESETS,
    VEHICLE_PRESETS,
    PresetError,
    VehicleRun,
    on_bank,
    on_random_banks,
    preset,
    vehicle_preset,
)
from sideslip_sim.sensors import noise_profile
from sideslip_sim.simulate import DT_S, SimulationError
from sideslip_sim.tir_file import TirError
from sideslip_sim.tire import load_tire
from sideslip_sim.vehicle import VehicleFileError, load_vehicle


def format_summary(summaries: Sequence[RunSummary], limit: int = 40) -> str:
    """A fixed-width table: one line per run (the first `limit`), then the totals."""
    head = (
        f"{'run':<34} {'samples':>7} {'|β|max°':>8} {'|a_y|max':>8} {'|r|max°/s':>9} "
        f"{'v0 km/h':>7} {'v_end':>6} {'μ':>4}"
    )
    lines = [head, "-" * len(head)]
    for s in summaries[:limit]:
        lines.append(
            f"{s.name[:34]:<34} {s.samples:>7} {s.peak_abs_beta_deg:>8.2f} "
            f"{s.peak_abs_ay_mps2:>8.2f} {s.peak_abs_yaw_rate_degps:>9.1f} "
            f"{s.speed_start_kmh:>7.1f} {s.speed_end_kmh:>6.1f} {s.mu:>4.2f}"
        )
    if len(summaries) > limit:
        lines.append(f"... {len(summaries) - limit} more runs (see {INDEX_FILE})")
    total = sum(s.samples for s in summaries)
    sim_time = total * DT_S
    lines.append(f"{len(summaries)} runs, {total} samples ({sim_time:.1f} s simulated at 400 Hz)")
    spun = [s.name for s in summaries if s.spun]
    if spun:
        lines.append(
            f"{len(spun)} run(s) spun (|β| > {SPIN_BETA_DEG:.0f}°), flagged in {INDEX_FILE}: "
            + ", ".join(spun[:5])
            + (" ..." if len(spun) > 5 else "")
        )
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="sideslip-generate",
        description=(
            "Simulate a preset of manoeuvres with the 14-DOF vehicle model and write one "
            "rosbag2 MCAP bag per run (noisy sensor topics + exact ground truth at 400 Hz), "
            "plus index.json with a summary of every run."
        ),
        epilog=(
            "presets on one car (--vehicle): paper-train (Table 3 grid), paper-test "
            "(Table 4 scenarios), randomized (seeded draws; see --count). Presets whose runs "
            "each have their own car: fleet (--count runs, four per car drawn by the seeded "
            "fleet sampler, μ 0.3-1.0), held-out (the six held-out cars at μ 1.0/0.7/0.4: "
            "for evaluation only). Training presets refuse a held-out car. Example: "
            "sideslip-generate --preset paper-test --out data/paper-test --noise paper"
        ),
    )
    parser.add_argument(
        "--preset", required=True, help=f"one of: {', '.join((*PRESETS, *VEHICLE_PRESETS))}"
    )
    parser.add_argument("--out", required=True, type=Path, help="output directory for the bags")
    parser.add_argument("--noise", default="paper", help="sensor noise profile: paper | none")
    parser.add_argument("--seed", type=int, default=0, help="base seed (noise, random draws)")
    parser.add_argument(
        "--vehicle",
        default=None,
        help="shipped vehicle name or path to a vehicle YAML (default paper_sedan); not "
        "for fleet and held-out, whose runs name their own cars",
    )
    parser.add_argument(
        "--count", type=int, default=100, help="runs of the randomized and fleet presets"
    )
    parser.add_argument(
        "--both-sides",
        action="store_true",
        help="fleet: every run turns the side it draws (by default only cornering does and "
        "the scripted lane changes, sines, sweeps and step steers open to the left, as in "
        "the data the shipped models were trained on; docs/evaluation/direction)",
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=min(2, os.cpu_count() or 1),
        help="worker processes (default: up to 2)",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace bags in a non-empty --out (other files are kept)",
    )
    parser.add_argument(
        "--imu-frame",
        choices=("level", "body"),
        default="level",
        help="level (default): the CG acceleration in the horizontal frame, as every shipped "
        "model learnt; body: specific force in the body frame with gravity's share through "
        "roll and pitch, as an unaided MEMS IMU reads (docs/evaluation/imu-mounting)",
    )
    parser.add_argument(
        "--imu-position",
        nargs=2,
        type=float,
        default=(0.0, 0.0),
        metavar=("X", "Y"),
        help="the IMU's place from the CG, x forward, y left [m] (default 0 0)",
    )
    parser.add_argument(
        "--bank",
        type=float,
        default=0.0,
        metavar="PCT",
        help="road crossfall [%%] under every run: a plane falling to the right of the run's "
        "start heading (< 0: to the left; roads drain at about 2.5 %%), ramped in over the "
        "first second (default 0: level); recorded in each bag's manoeuvre",
    )
    parser.add_argument(
        "--bank-spread",
        type=float,
        default=None,
        metavar="PCT",
        help="each run on its own crossfall, drawn uniformly in [-PCT, PCT] %% (seeded by "
        "--seed; the runs are otherwise those without it), e.g. 4 for training data that "
        "covers drained and gently superelevated roads; not with --bank",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary table")
    return parser


def _preset_runs(args: argparse.Namespace) -> list[VehicleRun]:
    """The runs the command line asks for; a held-out car in a training preset is an
    error (the held-out benchmark must stay unseen)."""
    if args.both_sides and args.preset != "fleet":
        raise PresetError(f"--both-sides is for --preset fleet, not {args.preset}")
    if args.preset in VEHICLE_PRESETS:
        if args.vehicle is not None:
            raise PresetError(f"--vehicle does not apply to --preset {args.preset}: its runs "
                              "name their own cars")  # fmt: skip
        return vehicle_preset(
            args.preset, seed=args.seed, count=args.count, both_sides=args.both_sides
        )
    maneuvers = preset(args.preset, seed=args.seed, count=args.count)
    vehicle = load_vehicle(args.vehicle or "paper_sedan")
    load_tire(str(vehicle.tire_path()))  # a bad tyre file is refused before any work
    if args.preset in TRAINING_PRESETS and is_held_out(vehicle):
        raise PresetError(
            f"--vehicle {args.vehicle} is a held-out car: the training preset "
            f"{args.preset} must never contain it (use --preset held-out to evaluate)"
        )
    return single_vehicle(vehicle, maneuvers)


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        noise_profile(args.noise)
        runs = _preset_runs(args)
        if args.bank and args.bank_spread is not None:
            raise PresetError("--bank and --bank-spread exclude each other")
        if args.bank:
            runs = [on_bank(r, args.bank) for r in runs]
        if args.bank_spread is not None:
            runs = on_random_banks(runs, args.bank_spread, args.seed)
        if args.jobs < 1:
            raise ValueError(f"--jobs must be >= 1, got {args.jobs}")
        imu = ImuMounting(tuple(args.imu_position), args.imu_frame)
        prepare_output(args.out, force=args.force)
    except (PresetError, VehicleFileError, TirError, OutputDirError, ValueError, OSError) as exc:
        print(f"sideslip-generate: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    started = time.perf_counter()
    try:
        summaries = generate(
            runs,
            args.out,
            noise=args.noise,
            seed=args.seed,
            preset_name=args.preset,
            jobs=args.jobs,
            progress=not args.quiet,
            imu=imu,
        )
    except (SimulationError, ManeuverError) as exc:
        print(f"sideslip-generate: run failed: {exc}", file=sys.stderr)
        return EXIT_RUN_FAILED
    wall = time.perf_counter() - started
    if not args.quiet:
        print(format_summary(summaries))
        total = sum(s.samples for s in summaries) * DT_S
        ratio = total / wall if wall > 0 else math.inf
        print(
            f"wrote {len(summaries)} bags to {args.out} in {wall:.1f} s "
            f"({ratio:.0f}x real time, {args.jobs} job(s))"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
