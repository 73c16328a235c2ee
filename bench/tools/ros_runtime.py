"""ROS runtime benchmarks over real DDS (loopback): sim node rate/jitter, estimator latency.

Three processes, as a user runs them: ``sideslip-sim`` at 400 Hz real time, and
``sideslip-estimator`` (``--backend``: kinematic, or pso_lstm = the shipped default
model through the streaming engine), both as child processes; this process is the
subscriber that measures. Receive times are taken in the subscription callbacks
(wall clock, ``time.time_ns``), so every figure includes DDS delivery:

* rate: IMU messages received per second over the window; drift: the difference
  between elapsed stamp time and elapsed receive time over the window;
* jitter: the inter-arrival interval of /vehicle/imu, p50/p99 of |interval − 2.5 ms|;
* latency: /sideslip/twist receive time − its stamp. The sim stamps each step with the
  wall time it is due, so this is sensor time → estimate in another process.

Run alone: ``python bench/tools/ros_runtime.py --seconds 30`` (``make bench`` runs it too).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistWithCovarianceStamped
from rclpy.context import Context
from sensor_msgs.msg import Imu

from sideslip_msgs_py import topics
from sideslip_msgs_py.messages import stamp_ns
from sideslip_msgs_py.nodes.qos import profile_for
from sideslip_msgs_py.nodes.runtime import SpinThread, make_executor

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/ when run as a script
from machine import emit_report

BIN = Path(sys.executable).parent
PERIOD_NS = 2_500_000


class Listener:
    """Receive times and stamps of the measured topics, in this process (``imu=False``:
    the estimator's outputs only, for a run where this process must load the machine
    as little as it can)."""

    def __init__(self, domain_id: int, *, imu: bool = True) -> None:
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node("bench_listener", context=self.context)
        self.imu: list[tuple[int, int]] = []
        self.twist: list[tuple[int, int]] = []
        self.status: list[Any] = []
        self.recording = False
        if imu:
            self.node.create_subscription(Imu, topics.IMU, self._on_imu, profile_for(topics.IMU))
        self.node.create_subscription(
            TwistWithCovarianceStamped,
            topics.SIDESLIP_TWIST,
            self._on_twist,
            profile_for(topics.SIDESLIP_TWIST),
        )
        self.node.create_subscription(
            DiagnosticArray,
            topics.SIDESLIP_STATUS,
            self.status.append,
            profile_for(topics.SIDESLIP_STATUS),
        )
        self.executor = make_executor(self.context)
        self.executor.add_node(self.node)
        self._spinner = SpinThread(self.executor, self.context, name="bench-listener")

    def _on_imu(self, msg: Imu) -> None:
        now = time.time_ns()
        if self.recording:
            self.imu.append((now, stamp_ns(msg)))

    def _on_twist(self, msg: TwistWithCovarianceStamped) -> None:
        now = time.time_ns()
        if self.recording:
            self.twist.append((now, stamp_ns(msg)))

    def close(self) -> None:
        self._spinner.close(self.node)  # in the order that cannot segfault


def _stop(proc: subprocess.Popen[bytes]) -> int:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        return proc.wait(10)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.wait()


def _percentiles(values: np.ndarray) -> dict[str, float]:
    return {
        "p50": float(np.percentile(values, 50)),
        "p99": float(np.percentile(values, 99)),
        "max": float(values.max()),
    }


def run(
    seconds: float = 30.0,
    executor: str = "events",
    domain_id: int = 91,
    backend: str = "kinematic",
) -> dict[str, Any]:
    """One measurement: sim + estimator + this listener for ``seconds`` of steady state."""
    env = dict(
        os.environ,
        ROS_DOMAIN_ID=str(domain_id),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        SIDESLIP_EXECUTOR=executor,
    )
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    listener = Listener(domain_id)
    duration = seconds + 15.0  # matching and warm-up before the measured window
    sim_log = tempfile.TemporaryFile()
    procs = [
        subprocess.Popen(
            [
                str(BIN / "sideslip-estimator"),
                "--ros-args",
                "-p",
                f"backend:={backend}",
                "-p",
                "status_rate_hz:=1.0",
            ],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        ),
        subprocess.Popen(
            [
                str(BIN / "sideslip-sim"),
                "--ros-args",
                "-p",
                "scenario:=random_steer",
                "-p",
                f"maneuver.duration_s:={duration:.1f}",
                # No wait_for_subscribers: it would need this listener on every topic,
                # and each extra subscription loads the process that measures. The
                # first seconds (matching) fall in the warm-up instead.
            ],
            env=env,
            stdout=sim_log,
            stderr=subprocess.STDOUT,
        ),
    ]
    try:
        deadline = time.monotonic() + 60.0
        # Warm-up: both the IMU and the estimate flowing into this process.
        listener.recording = True
        while not (listener.imu and listener.twist):
            if time.monotonic() > deadline:
                raise RuntimeError("benchmark: no data from the sim or the estimator")
            time.sleep(0.1)
        time.sleep(2.0)  # let start-up transients (first window, first run) pass
        listener.imu.clear()
        listener.twist.clear()
        time.sleep(seconds)
        listener.recording = False
    finally:
        codes = [_stop(p) for p in reversed(procs)]
        listener.close()
    imu = np.array(listener.imu, dtype=np.int64)
    twist = np.array(listener.twist, dtype=np.int64)
    recv, stamps = imu[:, 0], imu[:, 1]
    window_s = (recv[-1] - recv[0]) * 1e-9
    intervals_ms = np.diff(recv) * 1e-6
    jitter_ms = np.abs(intervals_ms - PERIOD_NS * 1e-6)
    expected = round((stamps[-1] - stamps[0]) / PERIOD_NS) + 1
    latency_ms = (twist[:, 0] - twist[:, 1]) * 1e-6
    processing = {}
    values: dict[str, str] = {}
    if listener.status:
        values = {kv.key: kv.value for kv in listener.status[-1].status[0].values}
        processing = {
            k: float(values[k]) for k in ("latency_ms_p50", "latency_ms_p99") if values[k] != "n/a"
        }
    rate = (len(recv) - 1) / window_s
    sim_log.seek(0)
    # The sim's own account of its schedule: publish time − due time of every step.
    lateness = [
        ln for ln in sim_log.read().decode(errors="replace").splitlines() if "lateness" in ln
    ]
    return {
        "executor": executor,
        "backend": backend,
        "model_id": values.get("model_id", "?") if listener.status else "?",
        "window_s": window_s,
        "sim_node": {
            "messages": len(recv),
            "missing_in_window": expected - len(recv),
            "rate_hz": rate,
            "rate_error_percent": (rate / 400.0 - 1.0) * 100.0,
            "drift_ms": ((recv[-1] - recv[0]) - (stamps[-1] - stamps[0])) * 1e-6,
            "interval_ms": _percentiles(intervals_ms),
            "jitter_ms": _percentiles(jitter_ms),
            "stamp_to_receive_ms": _percentiles((recv - stamps) * 1e-6),
            "sim_log_lateness": lateness[-1].split("]: ", 1)[-1] if lateness else "n/a",
            "targets": {"rate_error_percent": 0.5, "jitter_ms_p99": 1.0},
        },
        "estimator_end_to_end_latency_ms": {
            **_percentiles(latency_ms),
            "estimates": len(latency_ms),
            "target_p99": 2.0 if backend == "kinematic" else 1.0,
            "in_node_processing_ms": processing,
        },
        "exit_codes": codes,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--executor", choices=["events", "single_threaded"], default="events")
    parser.add_argument("--backend", choices=["kinematic", "pso_lstm"], default="kinematic")
    parser.add_argument("--json", type=Path, help="also write the result here")
    args = parser.parse_args(argv)
    result = run(args.seconds, args.executor, backend=args.backend)
    emit_report(result, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
