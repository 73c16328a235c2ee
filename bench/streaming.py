"""Per-sample cost of the streaming engine (``StreamingLstm.push``) against the per-window
torch path (``PsoLstmBackend.update``), one CPU thread, measured in the same run.

For each model: random rows (the paper's channels, scaled like bench/inference.py), the
model's inputs z-scored once for the whole stream, then ``--warmup`` untimed and
``--calls`` timed samples. Each sample times, interleaved so that load on the machine
hits all paths alike:

* ``push``: ``StreamingLstm.push`` of the newest z-scored row (numpy, no torch,
  float64: exact up to float64 rounding);
* ``push_float32``: the same engine in float32 arithmetic (rounds like torch, not bit
  for bit);
* ``push_numba``: the same engine with the compiled float32 kernel (the default engine,
  ``engine=numba``);
* ``update``: ``PsoLstmBackend.update`` with ``engine=torch`` on the window, as
  bench/inference.py times it (the model's inputs of the whole window, the prior,
  ``torch.lstm`` and the head);
* ``update_numpy`` / ``update_numba``: ``PsoLstmBackend.update`` with ``engine=numpy``
  / ``engine=numba`` (the default): the newest row's inputs, one ``push``, the prior;
* ``torch_lstm``: the ``torch.lstm`` call plus head of that back-end alone, on the
  same float32 window (the network part that ``push`` replaces).

The paths' outputs are compared on every timed sample: ``max_abs_dy``, the largest
difference of the network output y (z-scored β) between ``push`` and both torch paths
(update's β̂ less the prior, and the torch call); ``max_abs_dy_float32`` the same for
``push_float32``, ``max_abs_dy_numba`` for ``push_numba`` and ``update_numba``. Models
that read the car's parameters or the UKF observer are refused (this bench feeds them
neither). ``--random bilstm:2x64`` adds random-weight models. ``--load N`` runs N
CPU-bound background processes (``while True: pass``) for the whole measurement.

    OMP_NUM_THREADS=1 python bench/streaming.py --json /tmp/streaming.json [--load 2]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
from inference import random_artifact
from machine import cpu_model, emit_report, git_commit

from sideslip_estimator.backends.pso_lstm import PsoLstmBackend
from sideslip_estimator.streaming import StreamingLstm
from sideslip_estimator.window import SampleWindow
from sideslip_msgs_py.artifact import expected_tensors, read_artifact, write_artifact
from sideslip_msgs_py.features import CHANNELS
from sideslip_msgs_py.model_inputs import columns_of_rows, input_matrix, prior_of_window

STEP_NS = 2_500_000
SHIPPED_DIR = (
    Path(__file__).resolve().parents[1] / "sideslip_estimator/sideslip_estimator/data/models"
)
DEFAULT_MODELS = (
    SHIPPED_DIR / "pso_lstm_paper.safetensors",
    SHIPPED_DIR / "fleet_lstm_paper.safetensors",
)


def _stats(ns: np.ndarray) -> dict[str, float]:
    us = ns / 1e3
    return {
        "p50_us": float(np.percentile(us, 50)),
        "p90_us": float(np.percentile(us, 90)),
        "p99_us": float(np.percentile(us, 99)),
        "max_us": float(us.max()),
        "mean_us": float(us.mean()),
    }


def bench_model(path: Path, calls: int, warmup: int) -> dict[str, object]:
    """Timings [us] of push, update and the torch call alone on the same samples."""
    tensors, meta = read_artifact(path)
    if meta.needs_observer or meta.needs_vehicle:
        msg = f"{path}: reads the UKF observer or the car; this bench times kinematic models only"
        raise SystemExit(msg)
    w = meta.window_steps
    backend = PsoLstmBackend({"model_file": str(path), "threads": 1, "engine": "torch"}, w)
    streaming = PsoLstmBackend({"model_file": str(path), "threads": 1, "engine": "numpy"}, w)
    compiled = PsoLstmBackend({"model_file": str(path), "threads": 1, "engine": "numba"}, w)
    engine = StreamingLstm(tensors, meta)
    engine32 = StreamingLstm(tensors, meta, dtype=np.float32)
    fused = StreamingLstm(tensors, meta, kernel="numba")
    net = backend._window_net  # the torch back-end's network, set to one thread
    torch = net._torch

    rng = np.random.default_rng(1)
    scale = np.array([5.0, 0.5, 0.5, 4.0, 0.2, 0.02])
    rows = rng.normal(0.0, 1.0, (calls + warmup + w - 1, len(CHANNELS))) * scale
    rows[:, 0] += 20.0
    columns = columns_of_rows(rows, meta.channels)
    mean, std = np.asarray(meta.feature_mean), np.asarray(meta.feature_std)
    inputs = (input_matrix(columns, meta.features) - mean) / std

    window = SampleWindow(w, len(CHANNELS))
    x32 = torch.zeros(1, w, len(meta.features), dtype=torch.float32)
    weights, state = net._weights, net._state
    head = net._head
    bi = meta.directions == 2
    times = np.zeros((7, calls), dtype=np.int64)
    max_dy = max_dy32 = max_dy_fused = 0.0
    clock = time.perf_counter_ns
    for i, row in enumerate(rows):
        window.push(row, i * STEP_NS)
        t0 = clock()
        y = engine.push(inputs[i])
        t1 = clock()
        y32 = engine32.push(inputs[i])
        t6 = clock()
        y_fused = fused.push(inputs[i])
        t9 = clock()
        r, s = window.rows(), window.stamps_ns()
        t7 = clock()
        streamed = streaming.update(r, s)  # called on every row, as the estimator does
        t8 = clock()
        streamed_fused = compiled.update(r, s)
        t10 = clock()
        if not window.full:
            continue
        t2 = clock()
        estimate = backend.update(r, s)
        t3 = clock()
        x32.numpy()[0] = inputs[i - w + 1 : i + 1]
        t4 = clock()
        with torch.inference_mode():
            out, _, _ = torch.lstm(x32, state, weights, True, meta.layers, 0.0, False, bi, True)
            y_torch = torch.nn.functional.linear(out[:, -1, :], head.weight, head.bias).item()
        t5 = clock()
        k = i - (w - 1) - warmup
        if k < 0:
            continue
        times[:, k] = (t1 - t0, t6 - t1, t3 - t2, t5 - t4, t8 - t7, t9 - t6, t10 - t8)
        prior = 0.0
        if meta.prior != "none":
            prior = prior_of_window(columns_of_rows(r, meta.channels), meta.prior, meta.dt_s)
        assert y is not None and y32 is not None and estimate is not None
        y_update = (estimate.beta_rad - prior - meta.beta_mean) / meta.beta_std
        assert streamed is not None
        y_streamed = (streamed.beta_rad - prior - meta.beta_mean) / meta.beta_std
        max_dy = max(max_dy, abs(y - y_torch), abs(y - y_update), abs(y_streamed - y_update))
        max_dy32 = max(max_dy32, abs(y32 - y_torch), abs(y32 - y_update))
        assert y_fused is not None and streamed_fused is not None
        y_streamed_fused = (streamed_fused.beta_rad - prior - meta.beta_mean) / meta.beta_std
        max_dy_fused = max(max_dy_fused, abs(y_fused - y_torch), abs(y_streamed_fused - y_update))
    push, push32, update, core, update_numpy, push_numba, update_numba = (_stats(t) for t in times)
    return {
        "architecture": f"{meta.architecture} {meta.layers}x{meta.hidden_units}",
        "features": len(meta.features),
        "window_steps": w,
        "calls": calls,
        "push": push,
        "push_float32": push32,
        "update": update,
        "update_numpy": update_numpy,
        "push_numba": push_numba,
        "update_numba": update_numba,
        "torch_lstm": core,
        "update_over_update_numba_p50": update["p50_us"] / update_numba["p50_us"],
        "update_over_update_numba_p99": update["p99_us"] / update_numba["p99_us"],
        "torch_lstm_over_push_numba_p50": core["p50_us"] / push_numba["p50_us"],
        "torch_lstm_over_push_numba_p99": core["p99_us"] / push_numba["p99_us"],
        "update_over_update_numpy_p50": update["p50_us"] / update_numpy["p50_us"],
        "update_over_update_numpy_p99": update["p99_us"] / update_numpy["p99_us"],
        "update_over_push_p50": update["p50_us"] / push["p50_us"],
        "update_over_push_p99": update["p99_us"] / push["p99_us"],
        "torch_lstm_over_push_p50": core["p50_us"] / push["p50_us"],
        "torch_lstm_over_push_p99": core["p99_us"] / push["p99_us"],
        "update_over_push_float32_p50": update["p50_us"] / push32["p50_us"],
        "update_over_push_float32_p99": update["p99_us"] / push32["p99_us"],
        "max_abs_dy": max_dy,
        "max_abs_dy_float32": max_dy32,
        "max_abs_dy_numba": max_dy_fused,
        "max_abs_dbeta_numba_rad": max_dy_fused * meta.beta_std,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        description="p50/p99 [us] of StreamingLstm.push against PsoLstmBackend.update "
        "(per-window torch) on the same samples, one thread.",
    )
    p.add_argument("--calls", type=int, default=10_000, help="timed samples per model (10000)")
    p.add_argument("--warmup", type=int, default=500, help="untimed samples first (500)")
    p.add_argument("--json", type=Path, metavar="PATH", help="also write the JSON here")
    p.add_argument(
        "--note", default="", help="free text stored with the figures (e.g. the machine's load)"
    )
    p.add_argument(
        "--random",
        nargs="*",
        default=[],
        metavar="ARCH:LAYERSxHIDDEN",
        help="also time random-weight models of the paper's channels, e.g. bilstm:2x64",
    )
    p.add_argument(
        "--model",
        type=Path,
        nargs="*",
        default=list(DEFAULT_MODELS),
        help="artifacts to time (default: shipped pso_lstm_paper and fleet_lstm_paper)",
    )
    p.add_argument(
        "--load", type=int, default=0, help="CPU-bound background processes meanwhile (0)"
    )
    args = p.parse_args(argv)

    import torch

    torch.set_num_threads(1)
    burners = [
        subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.load)
    ]
    try:
        results = measure(args)
    finally:
        for burner in burners:
            burner.kill()
            burner.wait()
    report = {
        "date_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "commit": git_commit(),
        "machine": {
            "cpu": cpu_model(),
            "cores": os.cpu_count(),
            "python": platform.python_version(),
            "load_avg_1min": os.getloadavg()[0],
        },
        "numpy": np.__version__,
        "torch": torch.__version__,
        "threads": 1,
        "background_cpu_bound_processes": args.load,
        "note": args.note,
        "command": " ".join(["python", "bench/streaming.py", *(argv or sys.argv[1:])]),
        "models": results,
    }
    emit_report(report, args.json)
    return 0


def measure(args: argparse.Namespace) -> dict[str, object]:
    """Every model's timings (:func:`bench_model`), by name."""
    results = {}
    for model in args.model:
        results[model.name] = bench_model(model, args.calls, args.warmup)
        print(f"{model.name}: {results[model.name]}", file=sys.stderr)
    with tempfile.TemporaryDirectory(prefix="sideslip-bench-") as tmp:
        for spec in args.random:
            architecture, _, size = spec.partition(":")
            layers, _, hidden = size.partition("x")
            path = random_artifact(Path(tmp) / "m.safetensors", architecture, int(hidden))
            tensors, meta = read_artifact(path)
            if int(layers) != 1:  # random_artifact writes one layer
                meta = dataclasses.replace(meta, layers=int(layers))
                rng = np.random.default_rng(0)
                bound = 1.0 / np.sqrt(int(hidden))
                tensors = {
                    name: rng.uniform(-bound, bound, shape).astype(np.float32)
                    for name, shape in expected_tensors(meta).items()
                }
                write_artifact(path, tensors, meta, force=True)
            results[f"random:{spec}"] = bench_model(path, args.calls, args.warmup)
            print(f"random:{spec}: {results[f'random:{spec}']}", file=sys.stderr)
    return results


if __name__ == "__main__":
    sys.exit(main())
