"""What the estimator's Y_a check (``imu_scale.mode`` report / apply) costs per sample.

A 10-minute random-steer drive of paper_sedan at 400 Hz (the simulator's exact signals)
fed row by row through :meth:`ImuScale.feed`, as the estimator core does for every
accepted sample: the time of each call (p50, p99, max: the max is the sample that closes
a chunk and fits it), and the chunks fitted. The node's per-sample budget is the 2.5 ms
between samples; the back-ends take 66 µs (``fleet_lstm_paper``) to 0.7 ms per sample.

    python bench/imu_scale.py [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from sideslip_estimator.imu_scale import ImuScale, ImuScaleParams
from sideslip_estimator.inputs import X_V, Y_A, YAW_RATE
from sideslip_msgs_py.features import CHANNELS
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.sensors import exact_samples
from sideslip_sim.simulate import simulate
from sideslip_sim.vehicle import load_vehicle


def run(seconds: float = 600.0) -> dict[str, float]:
    m = Maneuver("imu_scale", "random_steer", seconds, 80.0, 400.0, seed=1)
    s = exact_samples(simulate(load_vehicle("paper_sedan"), m), start_stamp_ns=10**18)
    rows = np.zeros((len(s.stamp_ns), len(CHANNELS)))
    rows[:, X_V], rows[:, YAW_RATE], rows[:, Y_A] = s.x_v_mps, s.yaw_rate_radps, s.y_a_mps2
    scale = ImuScale(ImuScaleParams(mode="apply"), max_gap_s=0.1)
    times = np.empty(len(rows))
    for i, (row, stamp) in enumerate(zip(rows, s.stamp_ns.tolist(), strict=True)):
        started = time.perf_counter()
        scale.feed(row, stamp)
        times[i] = time.perf_counter() - started
    us = times * 1e6
    return {
        "samples": len(rows),
        "rate_hz": 400.0,
        "us_per_sample_p50": float(np.percentile(us, 50)),
        "us_per_sample_p99": float(np.percentile(us, 99)),
        "us_max": float(us.max()),
        "chunks_fitted": scale.online.completed,
        "scale": None if scale.online.estimate is None else scale.online.estimate.scale,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--json", type=Path)
    p.add_argument("--seconds", type=float, default=600.0)
    args = p.parse_args(argv)
    got = run(args.seconds)
    print(json.dumps(got, indent=2))
    if args.json:
        args.json.write_text(json.dumps(got))
    return 0


if __name__ == "__main__":
    sys.exit(main())
