"""Closing a spinning rclpy node under load, many times: does the process survive?

Why it exists: once in about four CI runs the pytest process died of SIGSEGV while a
test's probe (``tests/ros_support.Probe``) was torn down with messages still arriving.
The probe destroyed its node while its spin thread could still be inside ``spin_once``
(not thread-safe in rclpy, ros2/rclpy#255 and #260). This tool repeats that moment:
a child publishes ``Imu`` at about 2 kHz; each trial is a fresh process that creates a
probe from ``--probe-dir``'s ``ros_support.py``, receives 50 messages and closes it.
Exit codes are counted (0 survived, 139 = −SIGSEGV through the shell convention,
124 = hung past ``--trial-timeout``).

    python bench/tools/probe_close_stress.py --trials 300                  # tests/ as it is
    python bench/tools/probe_close_stress.py --trials 300 --probe-dir OLD   # another copy

Not part of ``make bench``: it measures a failure rate, not a speed.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

PUBLISHER = """
import time, rclpy
from sensor_msgs.msg import Imu
rclpy.init()
node = rclpy.create_node("stress_pub")
pub = node.create_publisher(Imu, "/stress", 10)
msg = Imu()
try:
    while rclpy.ok():
        pub.publish(msg)
        time.sleep(0.0005)
except (KeyboardInterrupt, Exception):
    pass
"""

TRIAL = """
import os, sys, time
sys.path.insert(0, os.environ["PROBE_DIR"])
from sensor_msgs.msg import Imu
import ros_support
probe = ros_support.Probe(int(os.environ["ROS_DOMAIN_ID"]))
inbox = probe.subscribe("/stress", Imu)
deadline = time.monotonic() + 10
while len(inbox) < 50 and time.monotonic() < deadline:
    time.sleep(0.01)
probe.close()
sys.exit(0 if len(inbox) >= 50 else 3)
"""


def _code(returncode: int) -> int:
    """A child's exit code as a shell prints it (a signal N reads 128 + N)."""
    return 128 - returncode if returncode < 0 else returncode


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=300)
    p.add_argument("--probe-dir", type=Path, default=ROOT / "tests")
    p.add_argument("--domain-id", type=int, default=77)
    p.add_argument("--trial-timeout", type=float, default=30.0, help="seconds per trial")
    args = p.parse_args(argv)
    if not (args.probe_dir / "ros_support.py").is_file():
        p.error(f"--probe-dir {args.probe_dir} has no ros_support.py")
    env = dict(
        os.environ,
        ROS_DOMAIN_ID=str(args.domain_id),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        PROBE_DIR=str(args.probe_dir.resolve()),
    )
    publisher = subprocess.Popen([sys.executable, "-c", PUBLISHER], env=env)
    counts: collections.Counter[int] = collections.Counter()
    try:
        for _ in range(args.trials):
            try:
                done = subprocess.run(
                    [sys.executable, "-c", TRIAL],
                    env=env,
                    capture_output=True,
                    timeout=args.trial_timeout,
                )
                counts[_code(done.returncode)] += 1
            except subprocess.TimeoutExpired:
                counts[124] += 1
    finally:
        publisher.send_signal(signal.SIGINT)
        publisher.wait(10)
    print(json.dumps({"probe_dir": str(args.probe_dir), "exit_codes": dict(counts)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
