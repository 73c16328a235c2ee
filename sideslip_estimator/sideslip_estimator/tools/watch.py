"""``sideslip-watch``: the estimate against the ground truth, live, and a summary at the end.

Subscribes to /sideslip/twist and /vehicle/ground_truth/twist (from the simulator or a
bag with a reference sensor), pairs them by header stamp and prints one line per
second (β̂, β, error) and, on SIGINT/SIGTERM or after ``--duration``, the MAE, RMSE and
max error in degrees over every pair. Exit 0; 1 when no pair was seen.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np
import rclpy.node
from rclpy.clock import Clock, ClockType

from sideslip_msgs_py import topics
from sideslip_msgs_py.messages import RclpyMessages, stamp_ns
from sideslip_msgs_py.nodes.qos import profile_for
from sideslip_msgs_py.nodes.runtime import StopFlag, run, user_args

PENDING_LIMIT = 4000  # unpaired messages kept per side (10 s at 400 Hz)


class Watcher(rclpy.node.Node):
    def __init__(self, flag: StopFlag, duration_s: float | None, quiet: bool) -> None:
        super().__init__("sideslip_watch")
        m = RclpyMessages()
        self._estimates: dict[int, float] = {}
        self._truth: dict[int, float] = {}
        self.errors_rad: list[float] = []
        self._quiet = quiet
        self.create_subscription(
            m.TwistWithCovarianceStamped,
            topics.SIDESLIP_TWIST,
            self._on_estimate,
            profile_for(topics.SIDESLIP_TWIST),
        )
        self.create_subscription(
            m.TwistStamped,
            topics.GROUND_TRUTH_TWIST,
            self._on_truth,
            profile_for(topics.GROUND_TRUTH_TWIST),
        )
        # Subscribed so that a simulator waiting for subscribers on every topic starts.
        self.create_subscription(
            m.Float64,
            topics.GROUND_TRUTH_SIDESLIP,
            lambda _msg: None,
            profile_for(topics.GROUND_TRUTH_SIDESLIP),
        )
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(1.0, self._report, clock=steady)
        if duration_s is not None:
            self.create_timer(duration_s, lambda: flag.set("duration"), clock=steady)
        self._last_beta: tuple[float, float] | None = None

    def _pair(self, stamp: int) -> None:
        if stamp in self._estimates and stamp in self._truth:
            est, ref = self._estimates.pop(stamp), self._truth.pop(stamp)
            self.errors_rad.append(est - ref)
            self._last_beta = (est, ref)
        for pending in (self._estimates, self._truth):
            while len(pending) > PENDING_LIMIT:
                pending.pop(next(iter(pending)))

    def _on_estimate(self, msg: Any) -> None:
        lin = msg.twist.twist.linear
        stamp = stamp_ns(msg)
        self._estimates[stamp] = math.atan2(lin.y, lin.x)
        self._pair(stamp)

    def _on_truth(self, msg: Any) -> None:
        lin = msg.twist.linear
        stamp = stamp_ns(msg)
        self._truth[stamp] = math.atan2(lin.y, lin.x)
        self._pair(stamp)

    def _report(self) -> None:
        if self._quiet or self._last_beta is None:
            return
        est, ref = self._last_beta
        print(
            f"β̂ {math.degrees(est):+7.3f}°  β {math.degrees(ref):+7.3f}°  "
            f"error {math.degrees(est - ref):+6.3f}°  ({len(self.errors_rad)} pairs)",
            flush=True,
        )

    def close(self) -> None:
        err = np.degrees(np.asarray(self.errors_rad))
        if err.size == 0:
            print("no estimate could be paired with a ground-truth message", file=sys.stderr)
            return
        print(
            f"{err.size} estimates against ground truth: MAE {np.mean(np.abs(err)):.4f}°, "
            f"RMSE {np.sqrt(np.mean(err**2)):.4f}°, ME {np.mean(err):+.4f}°, "
            f"max |error| {np.max(np.abs(err)):.4f}°",
            flush=True,
        )


def main(argv: Sequence[str] | None = None) -> int:
    args_all = list(sys.argv if argv is None else argv)
    parser = argparse.ArgumentParser(
        prog="sideslip-watch",
        description=__doc__.splitlines()[0],
        epilog="ROS arguments go after --ros-args (e.g. -r /sideslip/twist:=/car/sideslip/twist).",
    )
    parser.add_argument("--duration", type=float, help="stop after this many seconds")
    parser.add_argument("--quiet", action="store_true", help="only the final summary")
    options = parser.parse_args(user_args(args_all))
    if options.duration is not None and not options.duration > 0:
        parser.error(f"--duration must be > 0, got {options.duration}")
    holder: dict[str, Watcher] = {}

    def make(flag: StopFlag) -> Watcher:
        holder["w"] = Watcher(flag, options.duration, options.quiet)
        return holder["w"]

    code = run(make, args_all)
    if code == 0 and "w" in holder and not holder["w"].errors_rad:
        return 1
    return code


if __name__ == "__main__":
    sys.exit(main())
