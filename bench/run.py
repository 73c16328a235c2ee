"""Benchmarks → bench/results.json (`make bench`).

Every figure is measured in this run on this machine; ratios compare simulated time with
wall-clock time measured in the same run. Targets (issue #2):
- single vehicle in the node path (one sample per call) >= 100x real time;
- batch simulation of paper-train >= 1000x real time: measured on one core and as the
  aggregate of all (2) cores;
- paper-train with paper noise, bags written, in < 60 s on this 2-core machine.
ROS runtime (issue #3, `bench/tools/ros_runtime.py`): sim node at 400 Hz real time over 30 s,
rate within 0.5 % and inter-message jitter p99 < 1 ms; estimator end-to-end latency
(sensor stamp → /sideslip/twist received in another process) p99 < 2 ms. Measured with
rclpy's EventsExecutor (the nodes' default) and, for comparison in the same run, the
pure-Python SingleThreadedExecutor.
"""

from __future__ import annotations

import argparse
import concurrent.futures as futures
import json
import multiprocessing
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

from machine import cpu_model, git_commit

from sideslip_sim.generate import generate, prepare_output, single_vehicle
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.presets import paper_train
from sideslip_sim.simulate import DT_S, Stepper, simulate
from sideslip_sim.vehicle import load_vehicle


def bench_node_path(vehicle, seconds: float = 60.0) -> dict[str, float]:
    """One vehicle stepped one 2.5-ms sample per Python call, as the sim node does."""
    m = Maneuver("node_path", "random_steer", seconds, 80.0, 400.0, seed=1)
    stepper = Stepper(vehicle, m)
    stepper.step()  # compile / load cache outside the timing
    started = time.perf_counter()
    while not stepper.done:
        stepper.step()
    wall = time.perf_counter() - started
    simulated = (len(stepper) - 1) * DT_S
    return {
        "simulated_s": simulated,
        "wall_s": wall,
        "real_time_ratio": simulated / wall,
        "us_per_step": wall / (len(stepper) - 1) * 1e6,
        "target_ratio": 100.0,
    }


def bench_batch_one_core(vehicle, repeats: int = 3) -> dict[str, float]:
    """paper-train simulated in this one process (no noise, no bag I/O), `repeats` times:
    this VM's timings scatter by ~15 %, so the median and the range are reported."""
    runs = paper_train()
    simulate(vehicle, Maneuver("warm", "straight", 0.01, 10.0, 0.0))
    walls = []
    for _ in range(repeats):
        started = time.perf_counter()
        samples = sum(len(simulate(vehicle, m)) for m in runs)
        walls.append(time.perf_counter() - started)
    wall = statistics.median(walls)
    return {
        "runs": len(runs),
        "samples": samples,
        "simulated_s": samples * DT_S,
        "repeats": repeats,
        "wall_s": wall,
        "real_time_ratio": samples * DT_S / wall,
        "real_time_ratio_min": samples * DT_S / max(walls),
        "real_time_ratio_max": samples * DT_S / min(walls),
        "target_ratio": 1000.0,
    }


def _simulate_count(vehicle, m) -> int:
    return len(simulate(vehicle, m))


def bench_batch_all_cores(vehicle, jobs: int) -> dict[str, float]:
    """paper-train simulated by `jobs` forked worker processes (no noise, no bag I/O)."""
    runs = paper_train()
    simulate(vehicle, Maneuver("warm", "straight", 0.01, 10.0, 0.0))  # compile before fork
    ctx = multiprocessing.get_context("fork")
    with futures.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
        list(pool.map(_simulate_count, [vehicle] * jobs, runs[:jobs]))  # start the workers
        started = time.perf_counter()
        samples = sum(pool.map(_simulate_count, [vehicle] * len(runs), runs))
        wall = time.perf_counter() - started
    return {
        "jobs": jobs,
        "runs": len(runs),
        "samples": samples,
        "simulated_s": samples * DT_S,
        "wall_s": wall,
        "real_time_ratio": samples * DT_S / wall,
        "target_ratio": 1000.0,
    }


def bench_generate_paper_train(vehicle, jobs: int) -> dict[str, float]:
    """sideslip-generate --preset paper-train --noise paper: simulation + noise + bags."""
    runs = paper_train()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "paper-train"
        prepare_output(out, force=False)
        started = time.perf_counter()
        summaries = generate(
            single_vehicle(vehicle, runs),
            out,
            noise="paper",
            seed=0,
            preset_name="paper-train",
            jobs=jobs,
            progress=False,
        )
        wall = time.perf_counter() - started
        size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
    samples = sum(s.samples for s in summaries)
    return {
        "jobs": jobs,
        "runs": len(summaries),
        "samples": samples,
        "messages": samples * 5,
        "wall_s": wall,
        "real_time_ratio": samples * DT_S / wall,
        "bag_bytes": size,
        "target_wall_s": 60.0,
    }


def bench_simulator(vehicle) -> dict[str, object]:
    print("simulator: node path (one step per call) ...", flush=True)
    node = bench_node_path(vehicle)
    print("simulator: batch paper-train on one core ...", flush=True)
    batch = bench_batch_one_core(vehicle)
    cores = min(2, os.cpu_count() or 1)
    print(f"simulator: batch paper-train on {cores} cores ...", flush=True)
    batch_all = bench_batch_all_cores(vehicle, cores)
    print(f"generator: paper-train with paper noise, {cores} jobs ...", flush=True)
    gen = bench_generate_paper_train(vehicle, jobs=cores)
    return {
        "single_vehicle_node_path": node,
        "batch_paper_train_one_core": batch,
        "batch_paper_train_all_cores": batch_all,
        "generate_paper_train_paper_noise": gen,
    }


def bench_training() -> dict[str, object]:
    """CPU training throughput on paper-train (stride 10 to keep `make bench` short), plus
    the GPU figures measured on the session's H100 (bench/training_throughput_h100.json,
    from `python training/scripts/measure_throughput.py --device cuda` there)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "training" / "scripts"))
    from measure_throughput import measure

    print("training: CPU throughput on paper-train (stride 10) ...", flush=True)
    with tempfile.TemporaryDirectory(prefix="sideslip-bench-train-") as tmp:
        out = Path(tmp) / "train"
        out.mkdir()
        generate(
            single_vehicle(load_vehicle("paper_sedan"), paper_train()),
            out,
            preset_name="paper-train",
            progress=False,
            jobs=min(2, os.cpu_count() or 1),
        )
        cpu = measure([str(out)], "cpu", stride=10)
    gpu_file = Path(__file__).with_name("training_throughput_h100.json")
    return {
        "cpu": cpu,
        "gpu_h100": json.loads(gpu_file.read_text()) if gpu_file.exists() else None,
        "gpu_note": "measured on the session's H100 (16 cores), stride 1, same script",
    }


SECTIONS = ("simulator", "ros", "training", "inference", "mirror_average", "streaming", "imu_scale")
"""What ``make bench`` runs; the soak only on request."""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench/results.json"))
    parser.add_argument(
        "--sections",
        nargs="+",
        choices=[*SECTIONS, "soak"],
        default=list(SECTIONS),
        help="which benchmark sections to run (others keep their previous results); soak "
        "(sim + default estimator + 2 CPU-bound processes, --soak-seconds) only on request",
    )
    parser.add_argument("--soak-seconds", type=float, default=600.0)
    parser.add_argument("--ros-seconds", type=float, default=30.0)
    args = parser.parse_args(argv)
    vehicle = load_vehicle("paper_sedan")
    results: dict[str, object] = {
        "date_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "commit": git_commit(),
        "machine": {
            "cpu": cpu_model(),
            "cores": os.cpu_count(),
            "python": sys.version.split()[0],
            "platform": platform.platform(),
        },
        "command": "make bench",
    }
    if "simulator" in args.sections:
        results["simulator"] = bench_simulator(vehicle)
    if "ros" in args.sections:
        from tools.ros_runtime import run as run_ros  # imports rclpy: only when asked for

        ros = {}
        for executor in ("events", "single_threaded"):
            print(f"ros: sim + estimator + listener, {executor} executor ...", flush=True)
            ros[executor] = run_ros(args.ros_seconds, executor)
        # The default back-end (the shipped model, streaming engine): the target
        # of p99 < 1 ms from sensor stamp to /sideslip in another process, idle.
        print("ros: the same with the default pso_lstm back-end ...", flush=True)
        ros["events_pso_lstm"] = run_ros(args.ros_seconds, "events", backend="pso_lstm")
        results["ros_runtime"] = ros
    if "training" in args.sections:
        results["training"] = bench_training()
    # The engines' timings are for one thread: numpy's BLAS (OpenBLAS, also under numba's
    # np.dot) would otherwise split an 80-unit step over both cores. A child process, as
    # BLAS reads the setting when it loads.
    one_thread = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    here = Path(__file__).resolve().parent
    if "inference" in args.sections:
        tmp = Path(tempfile.mkdtemp(prefix="sideslip-inference-")) / "inference.json"
        command = [sys.executable, str(here / "inference.py"), "--json", str(tmp)]
        subprocess.run(command, env=one_thread, check=True, stdout=subprocess.DEVNULL)
        results["inference"] = json.loads(tmp.read_text())
    if "mirror_average" in args.sections:
        # pso_lstm.mirror_average off and on for the models a car file selects, in one run.
        tmp = Path(tempfile.mkdtemp(prefix="sideslip-mirror-")) / "mirror.json"
        command = [sys.executable, str(here / "inference.py"), "--mirror-average-only"]
        command += ["--json", str(tmp)]
        subprocess.run(command, env=one_thread, check=True, stdout=subprocess.DEVNULL)
        results["mirror_average"] = json.loads(tmp.read_text())
    if "streaming" in args.sections:
        # The engine against the per-window torch path, idle and with two CPU-bound
        # background processes (issue 10's ratio under load).
        results["streaming"] = {}
        for label, load in (("idle", 0), ("load2", 2)):
            tmp = Path(tempfile.mkdtemp(prefix="sideslip-streaming-")) / "streaming.json"
            command = [sys.executable, str(here / "streaming.py"), "--json", str(tmp)]
            command += ["--load", str(load), "--note", label]
            subprocess.run(command, env=one_thread, check=True, stdout=subprocess.DEVNULL)
            results["streaming"][label] = json.loads(tmp.read_text())
    if "imu_scale" in args.sections:
        # The estimator's Y_a check (on by default) per accepted sample, one thread.
        tmp = Path(tempfile.mkdtemp(prefix="sideslip-imu-scale-")) / "imu_scale.json"
        command = [sys.executable, str(here / "imu_scale.py"), "--json", str(tmp)]
        subprocess.run(command, env=one_thread, check=True, stdout=subprocess.DEVNULL)
        results["imu_scale"] = json.loads(tmp.read_text())
    if "soak" in args.sections:
        from tools.soak import run as run_soak  # imports rclpy: only when asked for

        results["soak"] = run_soak(args.soak_seconds, load=2)
    sections = ("simulator", "ros_runtime", "training", "inference", "mirror_average")
    for section in (*sections, "streaming", "imu_scale", "soak"):
        if section in results:
            results[section]["measured"] = {  # type: ignore[index]
                "date_utc": results["date_utc"],
                "commit": results["commit"],
            }
    previous = json.loads(args.out.read_text()) if args.out.exists() else {}
    # Keep other sections (later issues add theirs); replace what this run measured.
    previous.update(results)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(previous, indent=2) + "\n")
    print(
        json.dumps(
            {k: v for k, v in results.items() if k in (*args.sections, "ros_runtime")}, indent=2
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
