"""The held-out benchmark (``sideslip-benchmark``): every estimator on cars no one trained on.

The command: its options, the checks of its input, and the order of the work. Each step
is a module of its own:

* :mod:`.benchmark_data`: the held-out bags (six cars no training set, PSO or filter
  tuning contains, at μ = 1.0, 0.7 and 0.4, eight runs each: 108), generated with
  ``--generate`` or read from ``--data``; a bag of any other car is refused;
* :mod:`.benchmark_estimators`: the networks (shipped and ``--model``) and the physics
  filters (single-track KF, UKF) with each car's true nominal parameters;
* :mod:`.benchmark_scores`: β̂ − β [deg] of every estimator on the same samples, per
  run, car × μ cell, car and overall; the pass/fail verdicts of issue 8; results.json;
* :mod:`.benchmark_report` and :mod:`.benchmark_figures`: README.md and figures/.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Final

import numpy as np
import yaml

from sideslip_msgs_py.data_source import mirror_average_on

from .benchmark_data import (
    PROG,
    BenchmarkError,
    GenerationError,
    HeldOutRun,
    expected_run_count,
    generate_held_out,
    limit_runs,
    load_held_out,
    mirrored_runs,
)
from .benchmark_estimators import (
    BASELINES,
    SMOOTHING_STEPS,
    Network,
    load_networks,
    physics_filters,
    predict,
    prepare_physics,
    read_physics_params,
    run_physics,
    write_params_files,
)
from .benchmark_figures import plot_all
from .benchmark_report import cell_table, readme_markdown, verdict_markdown
from .benchmark_scores import collect, results_json, summarize
from .config import WINDOW_STEPS
from .inputs import add_mirror_average_argument
from .physics_params import steering_limit_m

EXIT_BAD_INPUT: Final = 2
EXIT_RUN_FAILED: Final = 1


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description=(
            "Score every estimator on the held-out fleet: six cars that no training set "
            "contains, each at μ = 1.0, 0.7 and 0.4, through the Table 4 scenarios, a step "
            "steer and a sine sweep, with paper noise (sideslip-generate --preset held-out). "
            "Estimators: β = 0, the kinematic baseline atan2(Y_v, X_v) raw and smoothed, the "
            "single-track KF and the UKF (each car's true nominal parameters), and every "
            "network (the shipped models and --model files). Writes results.json, README.md "
            "(MAE, RMSE, R², max error per car × μ, per car, pass/fail of issue 8), "
            "figures/ and vehicles/ (each car's parameters) into --out."
        ),
        epilog=(
            "Example: sideslip-benchmark --data data/held-out --generate "
            "--out docs/evaluation/held-out --jobs 2"
        ),
    )
    p.add_argument(
        "--data",
        required=True,
        type=Path,
        help="folder of the held-out bags (sideslip-generate --preset held-out)",
    )
    p.add_argument(
        "--generate",
        action="store_true",
        help="(re)generate the held-out bags into --data first (paper noise, seed 0); "
        "--data must be new, empty or a held-out folder",
    )
    p.add_argument("--out", required=True, type=Path, help="report folder")
    p.add_argument(
        "--force",
        action="store_true",
        help="write into a non-empty --out (only the files this command writes are replaced)",
    )
    p.add_argument(
        "--model",
        action="append",
        default=[],
        metavar="LABEL=PATH",
        help="a .safetensors model to score under LABEL (repeatable; a bare PATH "
        "takes its label from the metadata)",
    )
    p.add_argument(
        "--no-default-models",
        action="store_true",
        help="do not score the models shipped with the estimator",
    )
    p.add_argument(
        "--physics-params",
        type=Path,
        metavar="FILE",
        help="YAML {single_track: {...}, ukf: {...}} of tuned noise settings "
        "(default: the back-ends' defaults); params_file is set per car",
    )
    p.add_argument(
        "--jobs",
        type=int,
        default=min(2, os.cpu_count() or 1),
        help="worker processes for the physics filters and --generate (default: up to 2)",
    )
    p.add_argument(
        "--runs-limit",
        type=int,
        metavar="N",
        help="score only the first N runs of every car × μ cell (quick looks)",
    )
    p.add_argument(
        "--both-ways",
        action="store_true",
        help="score every run and its mirror image (the same drive turned the other way; "
        "in the same cell): the fleet's training drives start most manoeuvres to the left, "
        "and so do the benchmark's (docs/evaluation/direction)",
    )
    add_mirror_average_argument(p, "every network")
    p.add_argument("--quiet", action="store_true", help="no progress bars or printed table")
    return p


def _check_out(out: Path, force: bool) -> None:
    if out.exists() and not out.is_dir():
        raise BenchmarkError(f"--out {out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise BenchmarkError(
            f"--out {out} is not empty; pass --force to replace the benchmark's files in it"
        )


def _check_runs(runs: Sequence[HeldOutRun], networks: Sequence[Network], window: int) -> None:
    short = [r.name for r in runs if len(r.run) < window]
    if short:
        raise BenchmarkError(f"run(s) shorter than the {window}-sample window: {', '.join(short)}")
    steps = np.concatenate([np.diff(r.run.samples.stamp_ns) for r in runs])
    period_s = float(np.median(steps)) * 1e-9
    for n in networks:
        if abs(n.meta.dt_s / period_s - 1.0) > 0.02:
            raise BenchmarkError(
                f"--model {n.path}: trained at {n.meta.dt_s * 1e3:.2f} ms, the "
                f"bags are at {period_s * 1e3:.2f} ms"
            )


def _git(*args: str) -> str:
    try:
        out = subprocess.run(
            ["git", *args],
            capture_output=True,
            text=True,
            check=False,
            cwd=Path(__file__).parent,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return ""
    return out.stdout.strip() if out.returncode == 0 else ""


def machine_info() -> dict[str, Any]:
    """Where the figures were measured: platform, CPU, commit and uncommitted changes."""
    cpu = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    commit = _git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = (
        bool(_git("status", "--porcelain", "--untracked-files=no")) if commit != "unknown" else None
    )
    return {
        "platform": platform.platform(),
        "python": platform.python_version(),
        "cpu": cpu,
        "cpu_count": os.cpu_count(),
        "commit": commit,
        "uncommitted_changes": dirty,
    }


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    progress = not args.quiet
    started = time.perf_counter()

    def fail(err: object) -> int:
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT

    try:
        if args.jobs < 1:
            raise BenchmarkError(f"--jobs must be >= 1, got {args.jobs}")
        if args.runs_limit is not None and args.runs_limit < 1:
            raise BenchmarkError(f"--runs-limit must be >= 1, got {args.runs_limit}")
        _check_out(args.out, args.force)
        networks = load_networks(args.model, shipped=not args.no_default_models)
        filters, notes = physics_filters(read_physics_params(args.physics_params))
        if args.generate:
            generate_held_out(args.data, jobs=args.jobs, progress=progress)
        runs = load_held_out(args.data, progress=progress)
        if args.runs_limit is not None:
            runs = limit_runs(runs, args.runs_limit)
        if args.both_ways:
            runs = [*runs, *mirrored_runs(runs)]
        window = networks[0].meta.window_steps if networks else WINDOW_STEPS
        _check_runs(runs, networks, window)
        params = prepare_physics(filters, runs, notes)
    except (BenchmarkError, OSError, ImportError) as err:
        return fail(err)
    except GenerationError as err:
        print(f"{PROG}: generation failed: {err}", file=sys.stderr)
        return EXIT_RUN_FAILED
    for note in notes:
        print(f"{PROG}: note: {note}", file=sys.stderr)
    if any(r.noise != "paper" for r in runs):
        print(
            f"{PROG}: note: bags with other noise than paper: the benchmark's figures are "
            "for paper noise",
            file=sys.stderr,
        )

    with tempfile.TemporaryDirectory(prefix="sideslip-benchmark-") as tmp:
        files = write_params_files(params, Path(tmp))
        physics = run_physics(
            runs, filters, files, window_steps=window, jobs=args.jobs, progress=progress
        )

    from tqdm import tqdm

    results = []
    for r in tqdm(
        runs, unit="run", desc="networks", disable=not progress or not networks, file=sys.stderr
    ):
        results.append(
            collect(
                r,
                window_steps=window,
                physics={f.label: physics[(r.name, f.label)] for f in filters},
                networks={
                    n.label: predict(n, r, mirror_average=args.mirror_average) for n in networks
                },
            )
        )
    labels = [*BASELINES, *(f.label for f in filters), *(n.label for n in networks)]
    summary = summarize(results, labels)
    for r in results:
        for lab in labels:
            if missing := r.without_estimate(lab):
                print(
                    f"{PROG}: note: {r.run.name}: {lab} gave no estimate for {missing} sample(s); "
                    "left out for every estimator",
                    file=sys.stderr,
                )

    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    figures = plot_all(summary, out / "figures", progress=progress)
    (out / "vehicles").mkdir(exist_ok=True)
    for r in runs:
        (out / "vehicles" / f"{r.vehicle_name}.yaml").write_text(
            f"# {r.vehicle_name}: held-out car (sideslip_sim.held_out), as its bags record it; "
            "sideslip_sim.vehicle.load_vehicle reads this file\n"
            + yaml.safe_dump(r.vehicle, sort_keys=True)
        )
    (out / "physics").mkdir(exist_ok=True)
    write_params_files(params, out / "physics")
    context = {
        "benchmark": "held-out",
        "command": shlex.join([PROG, *argv]),
        "when": datetime.now(UTC).isoformat(timespec="seconds"),
        "machine": machine_info(),
        "wall_s": round(time.perf_counter() - started, 1),
        "jobs": args.jobs,
        "data": str(args.data),
        "runs_scored": len(results),
        "runs_in_full_benchmark": expected_run_count() * (2 if args.both_ways else 1),
        "runs_limit_per_cell": args.runs_limit,
        "both_ways": args.both_ways,
        "mirror_average": args.mirror_average,
        "mirror_averaged": {
            n.label: mirror_average_on(args.mirror_average, n.meta.provenance) for n in networks
        },
        "window_steps": window,
        "smoothing_steps": SMOOTHING_STEPS,
        "physics_params_file": None if args.physics_params is None else str(args.physics_params),
        "physics_limits_stl_m": {r.vehicle_name: steering_limit_m(r.vehicle) for r in runs},
    }
    report = results_json(summary, networks, filters, notes, context)
    (out / "results.json").write_text(json.dumps(report, indent=1, allow_nan=False) + "\n")
    (out / "README.md").write_text(
        readme_markdown(summary, networks, filters, notes, context, figures)
    )
    if progress:
        print(f"## MAE [deg] per car × μ\n\n{cell_table(summary, 'mae_deg', min)}\n")
        print(verdict_markdown(summary, networks))
    print(
        f"{PROG}: wrote {out} ({len(results)} runs, {len(labels)} estimators) in "
        f"{time.perf_counter() - started:.0f} s",
        file=sys.stderr,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
