"""The estimator node: sensor topics in, /sideslip, /sideslip/twist, /sideslip/status out.

Plumbing only: messages are decoded through the contract's field mapping and handed
to :class:`~sideslip_estimator.estimator.Estimator`; what it returns is published, and
:class:`~sideslip_estimator.status.StatusTracker` keeps what the status reports.
Inputs use the sensor-data QoS (keep last 5): when messages arrive faster than the
node processes them, DDS drops the oldest, the gaps in IMU stamps are counted as
dropped samples, and latency stays bounded by that short queue.
``ros2 run sideslip_estimator estimator_node`` and the pip console script
``sideslip-estimator`` are this module's ``main``.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import rclpy.node
from rclpy.clock import Clock, ClockType

from sideslip_estimator.backends import BackendError, backend_factory
from sideslip_estimator.estimator import Estimator, Output
from sideslip_estimator.imu_scale import ImuScale
from sideslip_estimator.inputs import InputRejected
from sideslip_estimator.mapped_inputs import MappedInputs, mapped_inputs
from sideslip_estimator.node_parameters import PARAMETERS, NodeParams, help_page
from sideslip_estimator.status import StatusTracker, assess, input_publishers
from sideslip_msgs_py import topics
from sideslip_msgs_py.errors import BagError, MessageFieldError
from sideslip_msgs_py.messages import RclpyMessages, imu_fields, steering_fields, twist_fields
from sideslip_msgs_py.nodes.qos import profile_for
from sideslip_msgs_py.nodes.ros_parameters import declare
from sideslip_msgs_py.nodes.runtime import StopFlag, run, wants_help
from sideslip_msgs_py.outputs import (
    fill_sideslip_twist,
    sideslip_message,
    sideslip_twist_message,
    status_message,
)

NODE_NAME = "sideslip_estimator"


class EstimatorNode(rclpy.node.Node):
    def __init__(self, flag: StopFlag) -> None:
        super().__init__(NODE_NAME)
        del flag  # runs until signalled
        try:
            params = NodeParams.from_values(declare(self, PARAMETERS))
            factory = backend_factory(params.backend)
            backend_values = declare(self, factory.parameters, prefix=f"{params.backend}.")
            backend = factory(backend_values, params.core.window_steps)
            mapped = mapped_inputs(params.topic_map_file, backend)
        except (BackendError, ValueError) as err:
            self.get_logger().fatal(f"bad parameter: {err}")
            raise SystemExit(2) from None
        self.params = params
        imu_scale = None
        if params.imu_scale.mode != "off":
            imu_scale = ImuScale(params.imu_scale, params.core.max_gap_s)
            line = imu_scale.load()
            if line is not None:
                self.get_logger().info(line)
        self.core = Estimator(backend, params.core, imu_scale)
        self._save_error = ""  # the last state-file error logged (each logged once)
        self.msgs = msgs = RclpyMessages()
        self.mapper = None if mapped is None else mapped[0]
        self.inputs: dict[str, tuple[Any, str]] = {}  # topic -> (subscription, type name)
        for topic, msg_type, handler, type_name in self._inputs_to_subscribe(mapped):
            # Best effort, keep last 5: matches reliable and best-effort publishers alike.
            sub = self.create_subscription(msg_type, topic, handler, profile_for(topics.IMU))
            # Remapping may rename the topic: report and check the resolved name.
            self.inputs[topic] = (sub, type_name)
        self.tracker = StatusTracker(
            self.core.stats,
            [sub.topic_name for sub, _ in self.inputs.values()],
            params.frame_id,
            params.silence_timeout_s,
        )
        self.pub_beta = self._publisher(msgs.Float64, topics.SIDESLIP)
        self.pub_twist = self._publisher(msgs.TwistWithCovarianceStamped, topics.SIDESLIP_TWIST)
        self.pub_status = self._publisher(msgs.DiagnosticArray, topics.SIDESLIP_STATUS)
        self._twist_msg = sideslip_twist_message(msgs, 0, 0.0, 0.0, 0.0, 0.0)
        # On the steady clock: with use_sim_time the ROS clock stops when /clock does,
        # and that is exactly when the status must report the silence.
        self.create_timer(
            1.0 / params.status_rate_hz,
            self._publish_status,
            clock=Clock(clock_type=ClockType.STEADY_TIME),
        )
        self.get_logger().info(
            f"backend {backend.model_id}, window {params.core.window_steps} samples; "
            f"inputs {', '.join(self.tracker.last_rx)}"
        )
        for caveat in backend.caveats:
            self.get_logger().warning(caveat)

    def _publisher(self, msg_type: Any, topic: str) -> Any:
        return self.create_publisher(msg_type, topic, profile_for(topic))

    def _inputs_to_subscribe(self, mapped: MappedInputs | None) -> list[tuple[str, Any, Any, str]]:
        """(topic, message class, callback, type name) per input topic."""
        if mapped is not None:  # topics of another stack, through the topic map
            return [
                (topic, cls, partial(self._on_mapped, topic), name)
                for topic, (cls, name) in mapped[1].items()
            ]
        msgs, types = self.msgs, topics.TOPIC_TYPES
        return [
            (topics.IMU, msgs.Imu, self._on_imu, types[topics.IMU]),
            (topics.TWIST, msgs.TwistStamped, self._on_twist, types[topics.TWIST]),
            (topics.STEERING, msgs.JointState, self._on_steering, types[topics.STEERING]),
        ]

    # --- inputs ---------------------------------------------------------------------------
    def _received(self, topic: str) -> str:
        """Note the arrival; returns the topic's name as subscribed (after remapping)."""
        name = self.inputs[topic][0].topic_name
        self.tracker.received(name, time.monotonic())
        return name

    def _guard(self, action: Callable[[], Any]) -> Any:
        try:
            return action()
        except InputRejected as err:
            self._log_rejection(err.reason, str(err))
        except (MessageFieldError, BagError) as err:  # a message we cannot decode
            self.core.reject_message("bad_message", str(err))
            self._log_rejection("bad_message", str(err))
        return None

    def _check_frame(self, topic: str, frame_id: str) -> None:
        """A frame other than the contract's is used as is, but reported (WARN)."""
        line = self.tracker.frame_mismatch(topic, frame_id)
        if line is not None:
            self.get_logger().warning(f"frame mismatch: {line}")

    def _on_twist(self, msg: Any) -> None:
        name = self._received(topics.TWIST)
        self._check_frame(name, msg.header.frame_id)
        self._guard(lambda: self.core.on_twist(name, twist_fields(msg)))

    def _on_steering(self, msg: Any) -> None:
        name = self._received(topics.STEERING)
        self._guard(lambda: self.core.on_steering(name, steering_fields(msg, name)))

    def _on_imu(self, msg: Any) -> None:
        start = time.perf_counter()
        name = self._received(topics.IMU)
        self._check_frame(name, msg.header.frame_id)
        fields = imu_fields(msg)
        self.tracker.imu_received(fields.stamp_ns, time.monotonic())
        self._publish(self._guard(lambda: self.core.on_imu(name, fields)), start)

    def _on_mapped(self, topic: str, msg: Any) -> None:
        """A message on a topic of the topic map: the clock topic's forms a sample."""
        start = time.perf_counter()
        name = self._received(topic)
        mapper, now_ns = self.mapper, self.get_clock().now().nanoseconds
        assert mapper is not None
        fields = self._guard(lambda: mapper.on_message(topic, msg, now_ns))
        if fields is None:
            return
        twist, steering, imu = fields
        self._guard(lambda: self.core.on_twist(name, twist))
        self._guard(lambda: self.core.on_steering(name, steering))
        self.tracker.imu_received(imu.stamp_ns, time.monotonic())
        self._publish(self._guard(lambda: self.core.on_imu(name, imu)), start)

    def _publish(self, out: Output | None, start: float) -> None:
        if out is None:
            return
        est = out.estimate
        self.pub_beta.publish(sideslip_message(self.msgs, est.beta_rad))
        self.pub_twist.publish(
            fill_sideslip_twist(
                self._twist_msg,
                out.stamp_ns,
                out.v_x_mps,
                est.beta_rad,
                est.variance_rad2,
                self.params.velocity_variance_m2ps2,
            )
        )
        self.tracker.published(time.perf_counter() - start, est.variance_rad2, est.beyond_fit_range)

    def _log_rejection(self, reason: str, detail: str) -> None:
        if self.tracker.rejection_due(reason, time.monotonic()):
            count = self.core.stats.rejected[reason]
            self.get_logger().warning(f"rejected input ({reason}, {count} so far): {detail}")

    # --- status -----------------------------------------------------------------------------
    def _save_imu_scale(self, *, final: bool = False) -> None:
        """Keep the Y_a measurement in its state file (when a chunk was added)."""
        imu_scale = getattr(getattr(self, "core", None), "imu_scale", None)
        if imu_scale is None:  # off, or the node did not get as far as making it
            return
        error = imu_scale.save(final=final) or ""
        if error and error != self._save_error:
            self.get_logger().error(error)
        self._save_error = error

    def destroy_node(self) -> None:
        # The drive's last stretch joins the measurement before the node goes.
        self._save_imu_scale(final=True)
        super().destroy_node()

    def _publish_status(self) -> None:
        now_s = time.monotonic()
        self._save_imu_scale()
        publishers, wrong_types = input_publishers(
            (sub.topic_name, expected, self.get_publishers_info_by_topic(sub.topic_name))
            for sub, expected in self.inputs.values()
        )
        for line in self.tracker.new_wrong_types(wrong_types):
            self.get_logger().error(f"wrong message type: {line}")
        obs = self.tracker.observe(self.core, publishers, wrong_types, now_s)
        model = self.core.backend
        status = assess(obs, self.core.stats, self.params.backend, model.model_id, model.caveats)
        stamp = self.tracker.stamp_ns(
            self.get_clock().now().nanoseconds, time.monotonic(), time.time_ns()
        )
        self.pub_status.publish(
            status_message(
                self.msgs,
                stamp,
                level=status.level,
                name=f"{self.get_name()}: sideslip estimate",
                message=status.message,
                hardware_id=self.get_fully_qualified_name(),
                values=status.values,
            )
        )


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv if argv is None else argv)
    if wants_help(args):
        print(help_page())
        return 0
    return run(EstimatorNode, args)


if __name__ == "__main__":
    sys.exit(main())
