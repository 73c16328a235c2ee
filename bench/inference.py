"""Per-sample cost of the pso_lstm back-end: p50/p99 of one ``update()`` call, one CPU thread.

The estimator calls ``update()`` once per IMU sample (400 Hz, a 2.5-ms budget shared
with alignment, the window and publishing); the target is p99 < 0.5 ms for hidden
units <= 128. Each configuration gets an artifact of random weights (the cost does not
depend on their values), the paper's six features and a 100-step window, then
``--warmup`` untimed and ``--calls`` timed calls on a window that slides by one row per
call, as in the node, once per engine (``numba``: the streaming engine compiled, the
default; ``numpy``: the same in float64 numpy; ``torch``: the whole window through torch
per call) in the same run, with the ratios of torch to each streaming engine.
Models that read the car or the UKF get ``paper_sedan``'s files (the UKF then runs
inside ``update()`` and is timed with it; the network too, also where ``paper_sedan``
lies outside the model's training cars).

    python bench/inference.py --json /tmp/inference.json
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import yaml
from machine import cpu_model, emit_report, git_commit

from sideslip_estimator.backends.pso_lstm import PsoLstmBackend
from sideslip_estimator.window import SampleWindow
from sideslip_msgs_py.artifact import ModelMetadata, expected_tensors, write_artifact
from sideslip_msgs_py.features import CHANNELS

WINDOW_STEPS = 100
STEP_NS = 2_500_000
CONFIGS = (("lstm", 32), ("lstm", 64), ("lstm", 128), ("bilstm", 64))
TARGET_P99_US = 500.0


def random_artifact(path: Path, architecture: str, hidden: int, seed: int = 0) -> Path:
    """An artifact of random weights (scaled like torch's init) for the paper's features."""
    meta = ModelMetadata(
        architecture=architecture,
        hidden_units=hidden,
        layers=1,
        features=CHANNELS,
        window_steps=WINDOW_STEPS,
        dt_s=0.0025,
        feature_mean=(20.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        feature_std=(5.0, 0.5, 0.5, 4.0, 0.2, 0.02),
        beta_mean=0.0,
        beta_std=0.03,
        training_data_digest="random",
        provenance={"command": "bench/inference.py"},
    )
    rng = np.random.default_rng(seed)
    bound = 1.0 / np.sqrt(hidden)
    tensors = {
        name: rng.uniform(-bound, bound, shape).astype(np.float32)
        for name, shape in expected_tensors(meta).items()
    }
    return write_artifact(path, tensors, meta, force=True)


def car_values(path: Path, folder: Path) -> dict[str, str]:
    """``paper_sedan`` as the car of a model that reads one (vehicle file, ukf file).
    It lies outside the training cars of the models that record them, where the node
    would publish the UKF alone: ``outside_fleet: network`` runs their network anyway,
    so the timing is that of a car inside the range (UKF and network)."""
    from sideslip_msgs_py.artifact import read_artifact
    from sideslip_msgs_py.vehicle_description import VehicleDescription
    from sideslip_sim.vehicle import load_vehicle

    _, meta = read_artifact(path)
    values: dict[str, str] = {}
    if meta.needs_vehicle:
        car = folder / "paper_sedan.yaml"
        desc = VehicleDescription.from_mapping(dataclasses.asdict(load_vehicle("paper_sedan")))
        car.write_text(yaml.safe_dump(desc.to_dict()))
        values["vehicle_file"] = str(car)
    if meta.needs_observer:
        values["observer_params_file"] = "paper_sedan"
    if meta.envelope is not None:
        values["outside_fleet"] = "network"
    return values


def bench_engines(
    path: Path, calls: int, warmup: int, threads: int, extra: dict[str, str] | None = None
) -> dict[str, object]:
    """Every engine's timings on the same rows, in one run, and the ratios at p50/p99."""
    out: dict[str, object] = {
        e: bench_update(path, calls, warmup, threads, {**(extra or {}), "engine": e})
        for e in ("numba", "numpy", "torch")
    }
    for e in ("numba", "numpy"):
        for q in ("p50_us", "p99_us"):
            out[f"torch_over_{e}_{q.removesuffix('_us')}"] = (
                out["torch"][q] / out[e][q]  # type: ignore[index]
            )
    return out


def bench_update(
    path: Path, calls: int, warmup: int, threads: int, extra: dict[str, str] | None = None
) -> dict[str, float]:
    """Timings [us] of ``update()`` alone (the window push is outside the clock), called
    on every row as the estimator does; a model anchored on the UKF runs the filter
    inside ``update()``, so it is timed too."""
    backend = PsoLstmBackend(
        {"model_file": str(path), "threads": threads, **(extra or {})}, WINDOW_STEPS
    )
    window = SampleWindow(WINDOW_STEPS, len(CHANNELS))
    rng = np.random.default_rng(1)
    scale = np.array([5.0, 0.5, 0.5, 4.0, 0.2, 0.02])
    rows = rng.normal(0.0, 1.0, (calls + warmup + WINDOW_STEPS - 1, len(CHANNELS))) * scale
    rows[:, 0] += 20.0
    times = np.empty(calls)
    missing = 0
    clock = time.perf_counter_ns
    for i, row in enumerate(rows):
        window.push(row, i * STEP_NS)
        r, s = window.rows(), window.stamps_ns()
        started = clock()
        estimate = backend.update(r, s)
        elapsed = clock() - started
        k = i - (WINDOW_STEPS - 1) - warmup
        if k >= 0:
            times[k] = elapsed
            missing += estimate is None
    us = times / 1e3
    return {
        "calls": calls,
        "p50_us": float(np.percentile(us, 50)),
        "p90_us": float(np.percentile(us, 90)),
        "p99_us": float(np.percentile(us, 99)),
        "max_us": float(us.max()),
        "mean_us": float(us.mean()),
        "p99_within_target": bool(np.percentile(us, 99) < TARGET_P99_US),
        "calls_without_estimate": missing,
    }


def fitted_like(folder: Path) -> Path:
    """``fleet_ukf_measurable`` as a ``sideslip-fit --bags`` model would name it as its
    start, with a narrow range of recordings (|a_y| ≤ 2 m/s²) that the bench's rows leave
    most of the time: the cost of ``beyond_fit_range`` when both models run."""
    from sideslip_msgs_py.artifact import read_artifact, write_artifact
    from sideslip_msgs_py.uncertainty import FitRange, Uncertainty

    tensors, meta = read_artifact(SHIPPED_DIR / "fleet_ukf_measurable.safetensors")
    assert meta.uncertainty is not None
    unc = Uncertainty.from_dict(meta.uncertainty)
    unc = dataclasses.replace(unc, fit_range=FitRange(2.0, 0.05, 2.0 * unc.scale, WINDOW_STEPS))
    meta = dataclasses.replace(
        meta,
        uncertainty=unc.to_dict(),
        provenance={
            "init": "fleet_ukf_measurable.safetensors",
            "init_data": meta.training_data_digest,
        },
    )
    return write_artifact(folder / "fitted_like.safetensors", tensors, meta, force=True)


def bench_beyond_fit_range(
    folder: Path, calls: int, warmup: int, threads: int
) -> dict[str, object]:
    """A fitted model's ``update()`` with ``beyond_fit_range`` ``model`` (one network and
    filter) and ``start`` (the start model's beside it), in one run, and the ratios."""
    path = fitted_like(folder)
    extra = car_values(path, folder)  # the networks run although paper_sedan is outside
    out: dict[str, object] = {
        mode: bench_update(path, calls, warmup, threads, {**extra, "beyond_fit_range": mode})
        for mode in ("model", "start")
    }
    for q in ("p50_us", "p99_us"):
        out[f"start_over_model_{q.removesuffix('_us')}"] = (
            out["start"][q] / out["model"][q]  # type: ignore[index]
        )
    return out


def bench_mirror_average(
    models: list[Path], folder: Path, calls: int, warmup: int, threads: int
) -> dict[str, object]:
    """``update()`` of each model with ``mirror_average`` off and on (numba engine), in
    one run, and the ratios: the price of a second network pass (the UKF runs once)."""
    out: dict[str, object] = {}
    for model in models:
        extra = car_values(model, folder)
        row: dict[str, object] = {
            mode: bench_update(
                model, calls, warmup, threads, {**extra, "mirror_average": mode == "on"}
            )
            for mode in ("off", "on")
        }
        for q in ("p50_us", "p99_us"):
            row[f"on_over_off_{q.removesuffix('_us')}"] = (
                row["on"][q] / row["off"][q]  # type: ignore[index]
            )
        out[model.name] = row
        print(f"mirror_average {model.name}: {row}", file=sys.stderr)
    return out


SHIPPED_DIR = (
    Path(__file__).resolve().parents[1] / "sideslip_estimator/sideslip_estimator/data/models"
)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        description="p50/p99 of one pso_lstm update() (100-step window) per network size.",
    )
    p.add_argument("--calls", type=int, default=10_000, help="timed calls per size (10000)")
    p.add_argument("--warmup", type=int, default=500, help="untimed calls first (500)")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads (1)")
    p.add_argument("--json", type=Path, metavar="PATH", help="also write the JSON here")
    p.add_argument(
        "--model",
        type=Path,
        nargs="*",
        default=[
            SHIPPED_DIR / "pso_lstm_paper.safetensors",
            SHIPPED_DIR / "pso_lstm_measurable.safetensors",
            SHIPPED_DIR / "fleet_lstm_paper.safetensors",
            SHIPPED_DIR / "fleet_ukf_paper.safetensors",
            SHIPPED_DIR / "fleet_ukf_measurable.safetensors",
            SHIPPED_DIR / "fleet_ukf_merged.safetensors",
            SHIPPED_DIR / "fleet_ukf_ensemble.safetensors",
            SHIPPED_DIR / "fleet_ukf_ensemble_disturbance.safetensors",
        ],
        help="exported models to time as well (default: the shipped ones)",
    )
    p.add_argument(
        "--mirror-average-only",
        action="store_true",
        help="only pso_lstm.mirror_average off against on, for the shipped models that "
        "read the UKF and fleet_lstm_paper",
    )
    args = p.parse_args(argv)
    if args.mirror_average_only:
        with tempfile.TemporaryDirectory(prefix="sideslip-bench-") as tmp:
            names = ("fleet_lstm_paper", "fleet_ukf_paper", "fleet_ukf_measurable")
            ensembles = ("fleet_ukf_ensemble", "fleet_ukf_ensemble_disturbance")
            models = [SHIPPED_DIR / f"{n}.safetensors" for n in (*names, *ensembles)]
            timings = bench_mirror_average(models, Path(tmp), args.calls, args.warmup, 1)
        emit_report(
            {
                "date_utc": datetime.now(UTC).isoformat(timespec="seconds"),
                "commit": git_commit(),
                "machine": {"cpu": cpu_model(), "python": platform.python_version()},
                "engine": "numba",
                "window_steps": WINDOW_STEPS,
                "command": " ".join(["python", "bench/inference.py", *(argv or sys.argv[1:])]),
                "update": timings,
            },
            args.json,
        )
        return 0

    import torch  # for the version only; the back-end imports it itself

    results = {}
    with tempfile.TemporaryDirectory(prefix="sideslip-bench-") as tmp:
        for architecture, hidden in CONFIGS:
            file = Path(tmp) / f"{architecture}{hidden}.safetensors"
            path = random_artifact(file, architecture, hidden)
            key = f"{architecture}_h{hidden}"
            results[key] = bench_engines(path, args.calls, args.warmup, args.threads)
            print(f"{key}: {results[key]}", file=sys.stderr)
        for model in args.model:
            if model.exists():
                key = f"shipped:{model.name}"
                extra = car_values(model, Path(tmp))
                results[key] = bench_engines(model, args.calls, args.warmup, args.threads, extra)
                print(f"{key}: {results[key]}", file=sys.stderr)
        key = "fitted_beyond_fit_range"
        results[key] = bench_beyond_fit_range(Path(tmp), args.calls, args.warmup, args.threads)
        print(f"{key}: {results[key]}", file=sys.stderr)
    report = {
        "date_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "commit": git_commit(),
        "machine": {"cpu": cpu_model(), "python": platform.python_version()},
        "torch": torch.__version__,
        "threads": args.threads,
        "window_steps": WINDOW_STEPS,
        "features": len(CHANNELS),
        "target_p99_us": TARGET_P99_US,
        "command": " ".join(["python", "bench/inference.py", *(argv or sys.argv[1:])]),
        "update": results,
    }
    emit_report(report, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
