"""The estimator node: sensor topics in, /sideslip, /sideslip/twist, /sideslip/status out.

Plumbing only: messages are decoded through the contract's field mapping and handed
to :class:`~sideslip_estimator.estimator.Estimator`; what it returns is published.
Inputs use the sensor-data QoS (keep last 5): when messages arrive faster than the
node processes them, DDS drops the oldest, the gaps in IMU stamps are counted as
dropped samples, and latency stays bounded by that short queue.
``ros2 run sideslip_estimator estimator_node`` and the pip console script
``sideslip-estimator`` are this module's ``main``.
"""

from __future__ import annotations

import importlib
import math
import sys
import time
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import rclpy.node
from rclpy.clock import Clock, ClockType

from sideslip_estimator.backends import BackendError, backend_factory
from sideslip_estimator.estimator import Estimator
from sideslip_estimator.inputs import InputRejected
from sideslip_estimator.parameters import PARAMETERS, estimator_params
from sideslip_estimator.status import Counts, Observation, assess
from sideslip_msgs_py import topics
from sideslip_msgs_py.errors import BagError, MessageFieldError
from sideslip_msgs_py.live_inputs import LiveMapper
from sideslip_msgs_py.messages import RclpyMessages, imu_fields, steering_fields, twist_fields
from sideslip_msgs_py.nodes.parameters import declare
from sideslip_msgs_py.nodes.qos import profile_for
from sideslip_msgs_py.nodes.runtime import StopFlag, run, wants_help
from sideslip_msgs_py.outputs import (
    fill_sideslip_twist,
    sideslip_message,
    sideslip_twist_message,
    status_message,
)
from sideslip_msgs_py.parameters import help_text
from sideslip_msgs_py.topic_map import TopicMap, TopicMapError

NODE_NAME = "sideslip_estimator"
LOG_EVERY_S = 5.0  # repeated rejections of one kind are logged at most this often


class EstimatorNode(rclpy.node.Node):
    def __init__(self, flag: StopFlag) -> None:
        super().__init__(NODE_NAME)
        del flag  # runs until signalled
        try:
            v = declare(self, PARAMETERS)
            factory = backend_factory(v["backend"])
            backend_values = declare(self, factory.parameters, prefix=f"{v['backend']}.")
            params = estimator_params(v)
            backend = factory(backend_values, params.window_steps)
            for name in ("status_rate_hz", "silence_timeout_s"):
                if not (math.isfinite(v[name]) and v[name] > 0.0):
                    raise ValueError(f"{name} must be finite and > 0, got {v[name]}")
            if not (math.isfinite(v["velocity_sigma_mps"]) and v["velocity_sigma_mps"] >= 0.0):
                raise ValueError(
                    f"velocity_sigma_mps must be finite and >= 0, got {v['velocity_sigma_mps']}"
                )
            mapped = _mapped_inputs(str(v["topic_map_file"]), backend)
        except (BackendError, ValueError) as err:
            self.get_logger().fatal(f"bad parameter: {err}")
            raise SystemExit(2) from None
        self.core = Estimator(backend, params)
        self.backend_name = v["backend"]
        self.silence_timeout_s = float(v["silence_timeout_s"])
        self.var_vx = float(v["velocity_sigma_mps"]) ** 2
        self.frame_id = str(v["frame_id"])
        self.msgs = RclpyMessages()
        msgs = self.msgs
        self.inputs: dict[str, tuple[Any, str]] = {}
        self._last_rx: dict[str, float | None] = {}
        self.mapper: LiveMapper | None = None
        if mapped is None:
            subscriptions = [
                (topics.IMU, msgs.Imu, self._on_imu, topics.TOPIC_TYPES[topics.IMU]),
                (topics.TWIST, msgs.TwistStamped, self._on_twist, topics.TOPIC_TYPES[topics.TWIST]),
                (
                    topics.STEERING,
                    msgs.JointState,
                    self._on_steering,
                    topics.TOPIC_TYPES[topics.STEERING],
                ),
            ]
        else:  # topics of another stack, through the topic map
            self.mapper, classes = mapped
            subscriptions = [
                (topic, cls, partial(self._on_mapped, topic), name)
                for topic, (cls, name) in classes.items()
            ]
        for topic, msg_type, handler, type_name in subscriptions:
            # Best effort, keep last 5: matches reliable and best-effort publishers alike.
            sub = self.create_subscription(msg_type, topic, handler, profile_for(topics.IMU))
            # Remapping may rename the topic: report and check the resolved name.
            self.inputs[topic] = (sub, type_name)
            self._last_rx[sub.topic_name] = None
        self.pub_beta = self.create_publisher(
            msgs.Float64, topics.SIDESLIP, profile_for(topics.SIDESLIP)
        )
        self.pub_twist = self.create_publisher(
            msgs.TwistWithCovarianceStamped,
            topics.SIDESLIP_TWIST,
            profile_for(topics.SIDESLIP_TWIST),
        )
        self.pub_status = self.create_publisher(
            msgs.DiagnosticArray, topics.SIDESLIP_STATUS, profile_for(topics.SIDESLIP_STATUS)
        )
        self._twist_msg = sideslip_twist_message(self.msgs, 0, 0.0, 0.0, 0.0, 0.0)
        self._latencies: list[float] = []
        self._sigmas: list[float] = []
        self._seen = Counts.of(self.core.stats)
        self._logged: dict[str, float] = {}
        self._wrong_types_logged: set[str] = set()
        self._wrong_frames: dict[str, str] = {}  # topic -> the line reporting it
        self._last_imu: tuple[int, float] | None = None  # (stamp ns, monotonic s)
        # On the steady clock: with use_sim_time the ROS clock stops when /clock does,
        # and that is exactly when the status must report the silence.
        self.create_timer(
            1.0 / float(v["status_rate_hz"]),
            self._publish_status,
            clock=Clock(clock_type=ClockType.STEADY_TIME),
        )
        self.get_logger().info(
            f"backend {backend.model_id}, window {params.window_steps} samples; "
            f"inputs {', '.join(self._last_rx)}"
        )

    # --- inputs ---------------------------------------------------------------------------
    def _received(self, topic: str) -> str:
        """Note the arrival; returns the topic's name as subscribed (after remapping)."""
        name = self.inputs[topic][0].topic_name
        self._last_rx[name] = time.monotonic()
        return name

    def _guard(self, action: Callable[[], Any]) -> Any:
        try:
            return action()
        except InputRejected as err:
            self._log_rejection(err.reason, str(err))
        except MessageFieldError as err:
            self.core.reject_message("bad_message", str(err))
            self._log_rejection("bad_message", str(err))
        return None

    def _check_frame(self, topic: str, frame_id: str) -> None:
        """A frame other than the contract's is used as is, but reported (WARN)."""
        if frame_id != self.frame_id and self.frame_id and topic not in self._wrong_frames:
            line = (
                f"{topic}: frame_id '{frame_id}', expected '{self.frame_id}' "
                f"(used as if {self.frame_id})"
            )
            self._wrong_frames[topic] = line
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
        self._last_imu = (fields.stamp_ns, time.monotonic())
        self._publish(self._guard(lambda: self.core.on_imu(name, fields)), start)

    def _on_mapped(self, topic: str, msg: Any) -> None:
        """A message on a topic of the topic map: the clock topic's forms a sample."""
        start = time.perf_counter()
        name = self._received(topic)
        assert self.mapper is not None
        try:
            fields = self.mapper.on_message(topic, msg, self.get_clock().now().nanoseconds)
        except BagError as err:
            self.core.reject_message("bad_message", str(err))
            self._log_rejection("bad_message", str(err))
            return
        if fields is None:
            return
        twist, steering, imu = fields
        self._guard(lambda: self.core.on_twist(name, twist))
        self._guard(lambda: self.core.on_steering(name, steering))
        self._last_imu = (imu.stamp_ns, time.monotonic())
        self._publish(self._guard(lambda: self.core.on_imu(name, imu)), start)

    def _publish(self, out: Any, start: float) -> None:
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
                self.var_vx,
            )
        )
        self._latencies.append(time.perf_counter() - start)
        self._sigmas.append(math.sqrt(est.variance_rad2))

    def _log_rejection(self, reason: str, detail: str) -> None:
        now = time.monotonic()
        if now - self._logged.get(reason, -1e9) >= LOG_EVERY_S:
            self._logged[reason] = now
            count = self.core.stats.rejected[reason]
            self.get_logger().warning(f"rejected input ({reason}, {count} so far): {detail}")

    # --- status -----------------------------------------------------------------------------
    def _input_publishers(self) -> tuple[dict[str, list[str]], list[str]]:
        """Per input topic the nodes publishing the contract's type, and one line per
        publisher of another type (each logged once as an error)."""
        publishers: dict[str, list[str]] = {}
        wrong = []
        for sub, expected in self.inputs.values():
            nodes = publishers.setdefault(sub.topic_name, [])
            for info in self.get_publishers_info_by_topic(sub.topic_name):
                who = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
                if info.node_name == "_NODE_NAME_UNKNOWN_":
                    who = "(a node not discovered yet)"
                if info.topic_type == expected:
                    nodes.append(who)
                else:
                    wrong.append(
                        f"{sub.topic_name}: {who} publishes {info.topic_type}, expected {expected}"
                    )
        for line in wrong:
            if line not in self._wrong_types_logged:
                self._wrong_types_logged.add(line)
                self.get_logger().error(f"wrong message type: {line}")
        return publishers, wrong

    def _status_stamp(self) -> int:
        """The ROS time; with use_sim_time and no /clock (ROS time 0) the newest IMU
        stamp plus the steady time since it arrived, so the stamps still advance."""
        now = self.get_clock().now().nanoseconds
        if now > 0:
            return now
        if self._last_imu is not None:
            stamp, rx = self._last_imu
            return stamp + round((time.monotonic() - rx) * 1e9)
        return time.time_ns()

    def _publish_status(self) -> None:
        now = time.monotonic()
        counts = Counts.of(self.core.stats)
        new, self._seen = counts - self._seen, counts
        publishers, wrong_types = self._input_publishers()
        core = self.core
        obs = Observation(
            input_ages_s={t: (None if rx is None else now - rx) for t, rx in self._last_rx.items()},
            wrong_types=wrong_types,
            silence_timeout_s=self.silence_timeout_s,
            window_fill=core.fill,
            latencies_s=self._latencies,
            new=new,
            publishers=publishers,
            wrong_frames=list(self._wrong_frames.values()),
            input_rate_hz=core.input_rate_hz,
            expected_rate_hz=core.expected_rate_hz,
            rate_refused=core.rate_refused,
            held=core.held,
            future_stamps=core.stats.future_stamps,
            sigmas_rad=self._sigmas,
        )
        self._latencies, self._sigmas = [], []
        status = assess(obs, self.core.stats, self.backend_name, self.core.backend.model_id)
        self.pub_status.publish(
            status_message(
                self.msgs,
                self._status_stamp(),
                level=status.level,
                name=f"{self.get_name()}: sideslip estimate",
                message=status.message,
                hardware_id=self.get_fully_qualified_name(),
                values=status.values,
            )
        )


def _mapped_inputs(path: str, backend: Any) -> tuple[LiveMapper, dict[str, tuple[Any, str]]] | None:
    """The topic map's mapper and message class per topic (None without a map).

    Raises ValueError naming the file: a map that cannot be read or used live, a type
    that is not installed, or a model channel the map leaves out."""
    if not path:
        return None
    try:
        topic_map = TopicMap.load(path)
        types = topic_map.input_types()
    except TopicMapError as err:
        raise ValueError(f"topic_map_file: {err}") from None
    reads = set(getattr(backend, "channels", ()))
    missing = sorted(reads - set(topic_map.channels) - {"y_v_mps"})
    if "y_v_mps" in reads and "y_v_mps" not in topic_map.channels:
        missing.append("y_v_mps")
    if missing:
        raise ValueError(
            f"topic_map_file: {path} does not map {missing}, which {backend.model_id} reads"
        )
    classes = {}
    for topic, name in types.items():
        package, _, type_name = name.partition("/msg/")
        try:
            classes[topic] = (getattr(importlib.import_module(f"{package}.msg"), type_name), name)
        except (ImportError, AttributeError, ValueError):
            raise ValueError(
                f"topic_map_file: message type {name} of {topic} is not installed"
            ) from None
    return LiveMapper(topic_map), classes


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv if argv is None else argv)
    if wants_help(args):
        from sideslip_estimator.backends import BACKENDS

        groups = [("Parameters", PARAMETERS)] + [
            (f"Back-end {name} (parameters {name}.*)", f.parameters) for name, f in BACKENDS.items()
        ]
        print(
            help_text(
                "sideslip-estimator (ros2 run sideslip_estimator estimator_node): sideslip "
                "angle from the vehicle sensor topics, on /sideslip.",
                groups,
            )
        )
        return 0
    return run(EstimatorNode, args)


if __name__ == "__main__":
    sys.exit(main())
