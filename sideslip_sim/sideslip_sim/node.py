"""The simulator node: publishes the contract's sensor and ground-truth topics at 400 Hz.

Plumbing only: :mod:`.node_parameters` turns the declared parameters into
:class:`~.node_parameters.SimParams` and a :class:`~.stream.SampleStream` of each run's
samples and CDR bytes; this node publishes them from its own thread, paced by
:class:`~.pacing.Pacer` on an absolute schedule, while the executor keeps serving
parameters and discovery on the main thread. ``ros2 run sideslip_sim sim_node`` and the
pip console script ``sideslip-sim`` are this module's ``main``.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Sequence

import rclpy.node

from sideslip_msgs_py import topics
from sideslip_msgs_py.messages import RclpyMessages
from sideslip_msgs_py.nodes.qos import profile_for
from sideslip_msgs_py.nodes.ros_parameters import declare
from sideslip_msgs_py.nodes.runtime import StopFlag, run, wants_help
from sideslip_msgs_py.outputs import clock_message
from sideslip_sim.maneuvers import ManeuverError
from sideslip_sim.node_parameters import (
    PARAMETERS,
    STEP_HZ,
    ParameterError,
    SimParams,
    help_page,
    open_stream,
)
from sideslip_sim.pacing import Pacer
from sideslip_sim.tir_file import TirError
from sideslip_sim.vehicle import VehicleFileError

NODE_NAME = "sideslip_sim"


class SimNode(rclpy.node.Node):
    def __init__(self, flag: StopFlag) -> None:
        super().__init__(NODE_NAME)
        self._flag = flag
        try:
            self.params = p = SimParams.from_values(declare(self, PARAMETERS))
            self.stream = open_stream(p)
        except (ParameterError, ManeuverError, VehicleFileError, TirError, ValueError) as err:
            self.get_logger().fatal(f"bad parameter: {err}")
            raise SystemExit(2) from None
        wanted = topics.SAMPLE_TOPICS if p.ground_truth else topics.SENSOR_TOPICS
        msgs = RclpyMessages()
        self.msg_types = {
            topics.IMU: msgs.Imu,
            topics.TWIST: msgs.TwistStamped,
            topics.STEERING: msgs.JointState,
            topics.GROUND_TRUTH_TWIST: msgs.TwistStamped,
            topics.GROUND_TRUTH_SIDESLIP: msgs.Float64,
        }
        self.pubs = {t: self.create_publisher(self.msg_types[t], t, profile_for(t)) for t in wanted}
        self.clock_pub = None
        if p.publish_clock:
            self.clock_pub = self.create_publisher(
                msgs.Clock, topics.CLOCK, profile_for(topics.CLOCK)
            )
        self._msgs = msgs
        self.pacer = Pacer(p.real_time_factor, flag)
        self.get_logger().info(
            f"{p.scenario} on {self.stream.vehicle.name}: {len(self.stream.runs)} run(s), "
            f"noise {p.noise}, {STEP_HZ / p.decimation:g} Hz, "
            f"real_time_factor {p.real_time_factor:g}" + (", looping" if p.loop else "")
        )
        self._thread = threading.Thread(target=self._publish_loop, name="sim-publisher")
        self._thread.start()

    def _publish_loop(self) -> None:
        try:
            if not self._wait_for_subscribers():
                self._flag.set("error")
                return
            self._publish_runs()
        except Exception as err:  # a crash here must still stop the process cleanly
            self.get_logger().fatal(f"publisher thread failed: {err!r}")
            self._flag.set("error")
            raise
        self.get_logger().info(self.pacer.summary())
        self._flag.set("finished")

    def _wait_for_subscribers(self) -> bool:
        """Hold until every publisher has ``wait_for_subscribers`` subscribers.

        True when they are there (or a stop was requested meanwhile); False, after a
        log line naming the topics that lack them, when the timeout passed first.
        """
        n = self.params.wait_for_subscribers
        if not n:
            return True
        limit = self.params.wait_for_subscribers_timeout_s
        self.get_logger().info(
            f"waiting for {n} subscriber(s) on each of "
            f"{', '.join(p.topic_name for p in self.pubs.values())}"
            + (f" (at most {limit:g} s)" if limit > 0.0 else "")
        )
        deadline = time.monotonic() + limit
        while not self._flag.is_set():
            counts = {p.topic_name: p.get_subscription_count() for p in self.pubs.values()}
            missing = {t: c for t, c in counts.items() if c < n}
            if not missing:
                break
            if limit > 0.0 and time.monotonic() > deadline:
                lacking = ", ".join(f"{t} has {c}" for t, c in missing.items())
                self.get_logger().fatal(
                    f"gave up waiting after {limit:g} s (wait_for_subscribers_timeout_s): "
                    f"{lacking} subscriber(s), {n} wanted (wait_for_subscribers); "
                    "exiting without publishing"
                )
                return False
            self._flag.wait(0.05)
        return True

    def _publish_runs(self) -> None:
        order = [t for t in topics.SAMPLE_TOPICS if t in self.pubs]
        for chunk in self.stream:
            rows = [(self.pubs[t].publish, chunk.messages[t]) for t in order]
            stamps = chunk.samples.stamp_ns.tolist()
            self.get_logger().info(f"run {chunk.maneuver.name}: {len(stamps)} steps")
            for i, stamp in enumerate(stamps):
                if not self.pacer.wait_for(stamp):
                    return
                if self.clock_pub is not None:
                    self.clock_pub.publish(clock_message(self._msgs, stamp))
                for publish, messages in rows:
                    publish(messages[i].tobytes())
                self.pacer.count_published()

    def close(self) -> bool:
        """Stop the publishing thread; False if it is still running after 2 s (then the
        node must not be destroyed under it: :func:`~sideslip_msgs_py.nodes.runtime.run`)."""
        self._flag.set()
        self._thread.join(timeout=2.0)
        return not self._thread.is_alive()


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv if argv is None else argv)
    if wants_help(args):
        print(help_page())
        return 0
    return run(SimNode, args)


if __name__ == "__main__":
    sys.exit(main())
