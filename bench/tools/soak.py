"""Soak: sim at 400 Hz + the default estimator for minutes on a loaded machine; does every
sample add up, does the output keep flowing, does memory stay flat?

Processes, as a user runs them on this VM: ``sideslip-sim`` looping the paper-test runs
in real time (no ground-truth topics; it starts publishing once the estimator has
subscribed), ``sideslip-estimator`` with no parameters (the shipped PSO-LSTM through the
streaming engine), ``--load`` CPU-bound background processes (``while True: pass``),
and this process, which subscribes to /sideslip/twist and /sideslip/status only.

Measured:

* accounting: the IMU messages the sim published (its own count, logged at exit)
  against the estimator's accepted + rejected + dropped (+ held) from its last status:
  ``unreported`` is the difference (target 0);
* output gaps: /sideslip/twist stamps in order; a gap longer than 10 ms inside a run
  (runs are 0.5 s apart, and the window refills for 250 ms after each start: gaps over
  0.4 s are run boundaries), how many and the longest, beside the restarts by cause;
* latency: /sideslip/twist receive time − its stamp (the sim stamps each step with the
  wall time it is due), so sensor time → estimate in another process, under load;
* memory: the estimator's RSS every 5 s; growth = last − the sample at ``--warmup-s``.

Run: ``python bench/tools/soak.py --seconds 600 --load 2 --json docs/evaluation/soak/soak.json``
(``make bench`` runs a short one only with ``--sections soak``).
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

# Run as a script (python bench/tools/soak.py) bench/ must be on the path, as it is for
# bench/run.py, which imports this module.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from machine import cpu_model, emit_report, git_commit

from tools.ros_runtime import BIN, Listener, _percentiles, _stop

RUN_BOUNDARY_S = 0.4
GAP_LIMIT_S = 0.010


def _rss_kib(pid: int) -> int:
    text = Path(f"/proc/{pid}/status").read_text()
    return int(re.search(r"VmRSS:\s+(\d+)", text).group(1))  # type: ignore[union-attr]


def _accounted(status: dict[str, str]) -> int:
    keys = ("accepted_samples", "rejected_samples", "dropped_samples", "held_samples")
    return sum(int(status.get(k, "0")) for k in keys)


def run(
    seconds: float = 600.0,
    load: int = 2,
    domain_id: int = 93,
    warmup_s: float = 60.0,
    estimator_args: tuple[str, ...] = (),
) -> dict[str, Any]:
    env = dict(
        os.environ,
        ROS_DOMAIN_ID=str(domain_id),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        OMP_NUM_THREADS="1",
    )
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(load)]
    listener = Listener(domain_id, imu=False)
    listener.recording = True
    sim_log = tempfile.TemporaryFile()
    est_log = tempfile.TemporaryFile()
    estimator = subprocess.Popen(
        [str(BIN / "sideslip-estimator"), "--ros-args", *estimator_args],
        env=env,
        stdout=est_log,
        stderr=subprocess.STDOUT,
    )
    sim = subprocess.Popen(
        [
            str(BIN / "sideslip-sim"),
            "--ros-args",
            "-p",
            "scenario:=paper-test",
            "-p",
            "loop:=true",
            "-p",
            "ground_truth:=false",
            "-p",
            "wait_for_subscribers:=1",
        ],
        env=env,
        stdout=sim_log,
        stderr=subprocess.STDOUT,
    )
    rss: list[tuple[float, int]] = []
    started = time.monotonic()
    try:
        deadline = started + 90.0
        while not listener.twist:
            if time.monotonic() > deadline or sim.poll() is not None:
                raise RuntimeError("soak: no estimate within 90 s")
            time.sleep(0.1)
        t0 = time.monotonic()
        while (elapsed := time.monotonic() - t0) < seconds:
            rss.append((elapsed, _rss_kib(estimator.pid)))
            time.sleep(min(5.0, max(0.0, seconds - elapsed)))
        sim_code = _stop(sim)
        # The estimator has the last messages; its status (2 Hz) then counts them all.
        seen = len(listener.status)
        wait_until = time.monotonic() + 5.0
        while len(listener.status) < seen + 3 and time.monotonic() < wait_until:
            time.sleep(0.1)
        final = {kv.key: kv.value for kv in listener.status[-1].status[0].values}
    finally:
        for proc in (sim, estimator):
            _stop(proc)
        for b in burners:
            b.kill()
            b.wait()
        listener.close()
    sim_log.seek(0)
    sim_text = sim_log.read().decode(errors="replace")
    match = re.search(r"(\d+) steps published", sim_text)
    published = int(match.group(1)) if match else -1
    twist = np.array(listener.twist, dtype=np.int64)
    recv, stamps = twist[:, 0], np.sort(twist[:, 1])
    gaps_s = np.diff(stamps) * 1e-9
    inside = gaps_s[gaps_s < RUN_BOUNDARY_S]
    long_inside = inside[inside > GAP_LIMIT_S]
    rss_arr = np.array(rss, dtype=float)
    after = rss_arr[rss_arr[:, 0] >= warmup_s]
    growth_mib = float(after[-1, 1] - after[0, 1]) / 1024.0 if len(after) > 1 else float("nan")
    restarts = {k: int(v) for k, v in final.items() if k.startswith("restarts[")}
    rejected = {k: int(v) for k, v in final.items() if k.startswith("rejected[")}
    accounted = _accounted(final)
    return {
        "date_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "commit": git_commit(),
        "machine": {"cpu": cpu_model(), "cores": os.cpu_count()},
        "seconds": seconds,
        "background_cpu_bound_processes": load,
        "load_average_1min_at_end": os.getloadavg()[0],
        "estimator": {
            "backend": final.get("backend", "?"),
            "model_id": final.get("model_id", "?"),
            "args": list(estimator_args),
        },
        "accounting": {
            "published_by_sim": published,
            "accepted": int(final.get("accepted_samples", -1)),
            "rejected": int(final.get("rejected_samples", -1)),
            "rejected_by_reason": rejected,
            "dropped": int(final.get("dropped_samples", -1)),
            "held": int(final.get("held_samples", 0)),
            "unreported": published - accounted,
            "estimates": int(final.get("estimates", -1)),
            "restarts_by_cause": restarts,
            "input_rate_hz": final.get("input_rate_hz"),
        },
        "output_gaps": {
            "estimates_received": len(stamps),
            "run_boundaries": int((gaps_s >= RUN_BOUNDARY_S).sum()),
            "gaps_over_10ms_inside_runs": int(long_inside.size),
            "longest_gap_inside_runs_ms": float(inside.max() * 1e3) if inside.size else 0.0,
            "gap_ms_inside_runs": _percentiles(inside * 1e3) if inside.size else {},
        },
        "latency_stamp_to_receive_ms": _percentiles((recv - twist[:, 1]) * 1e-6),
        "estimator_rss_mib": {
            "warmup_s": warmup_s,
            "at_warmup": float(after[0, 1]) / 1024.0 if len(after) else float("nan"),
            "at_end": float(rss_arr[-1, 1]) / 1024.0,
            "growth_after_warmup": growth_mib,
            "target_growth": 5.0,
        },
        "sim_exit_code": sim_code,
        "sim_log_tail": sim_text.strip().splitlines()[-1:] if sim_text.strip() else [],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=600.0)
    parser.add_argument("--load", type=int, default=2, help="CPU-bound background processes")
    parser.add_argument("--warmup-s", type=float, default=60.0)
    parser.add_argument("--json", type=Path, help="also write the result here")
    args = parser.parse_args(argv)
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    result = run(args.seconds, args.load, warmup_s=min(args.warmup_s, args.seconds / 2))
    result["command"] = "python bench/tools/soak.py " + " ".join(argv or sys.argv[1:])
    emit_report(result, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
