"""The estimator node's inputs from another stack's topics, through a topic map, one
message at a time (no rclpy: the node hands each decoded message in)."""

from __future__ import annotations

import math
from typing import Any

from . import channels as registry
from . import topics
from .errors import BagError
from .features import feature_set
from .field_path import field_value
from .imu_frame import YawAcceleration, at_cg, level_accelerations, roll_pitch
from .message_fields import FIELDS_RECORDS, stamp_ns
from .topic_map import FieldSource, TopicMap, heading_yaw

_PARTNERS = (topics.TWIST, topics.STEERING)
"""The records built before the IMU's, in the order the core takes them."""


class LiveMapper:
    """The estimator node's inputs from mapped topics, one message at a time (no rclpy).

    Each message updates the channels its topic gives (value and stamp: ``header.stamp``,
    else the receive time). A message on the clock channel's topic then yields the
    core's three inputs, built from the latest values: the twist stamped as its
    ``x_v_mps`` source, the steering as its ``stl_m`` source (each record as the source
    of its first mapped channel), the IMU as the clock message. An unmapped ``y_v_mps``
    (any model input outside the ``measurable`` set) is passed as 0 (the node refuses
    models that read it), a channel that is no model input (the rack's rate) as NaN;
    an unmapped measurable channel (yaw rate, acceleration, ...) makes no sample.
    With ``imu.frame: body`` the accelerations are levelled with the latest attitude
    (no sample before the first one), and with ``imu.position_m`` moved to the CG (ṙ
    from the yaw rate of the samples, as :func:`~.topic_map_read.read_mapped_bag` does).
    """

    def __init__(self, topic_map: TopicMap) -> None:
        self.map = topic_map
        self.clock_topic = topic_map.channels[topic_map.clock].topic
        self._values: dict[str, tuple[int, float]] = {}
        self._yaw: float | None = None
        self._tilt: tuple[float, float] | None = None
        self._yaw_accel = YawAcceleration()
        self._by_topic: dict[str, list[tuple[str, FieldSource]]] = {}
        for name, src in topic_map.channels.items():
            self._by_topic.setdefault(src.topic, []).append((name, src))

    def on_message(self, topic: str, msg: Any, receive_ns: int) -> tuple[Any, Any, Any] | None:
        """Take one message; on the clock topic, ``(TwistFields, SteeringFields,
        ImuFields)`` for the core (else None).

        Raises:
            BagError: the message lacks a mapped field (the message names it).
        """
        stamp = stamp_ns(msg) if hasattr(msg, "header") else receive_ns
        heading = self.map.velocity_heading
        try:
            for name, src in self._by_topic.get(topic, ()):
                value = float(field_value(msg, src.field)) * src.scale + src.offset
                self._values[name] = (stamp, value)
            if heading is not None and heading.topic == topic:
                self._yaw = heading_yaw(field_value(msg, heading.field), heading.kind)
            attitude = self.map.imu_attitude
            if attitude is not None and attitude.topic == topic:
                self._tilt = roll_pitch(field_value(msg, attitude.field))
        except (AttributeError, KeyError, IndexError, TypeError, ValueError) as err:
            raise BagError(f"{topic}: a mapped field is missing or not a number: {err}") from None
        if topic != self.clock_topic:
            return None
        v = dict(self._values)
        moved = self.map.imu_position_m != (0.0, 0.0)
        # ṙ advances on every clock message, sample or not, as over a bag's clock stamps.
        r_dot = 0.0
        if moved:
            r_dot = self._yaw_accel.update(stamp, v.get("yaw_rate_radps", (0, math.nan))[1])
        if any(n not in v for n in feature_set("measurable")):
            return None
        if heading is not None:
            if self._yaw is None:
                return None
            x_v, y_v = v["x_v_mps"][1], v.get("y_v_mps", (0, 0.0))[1]
            c, s = math.cos(self._yaw), math.sin(self._yaw)
            v["x_v_mps"] = (v["x_v_mps"][0], c * x_v + s * y_v)
            v["y_v_mps"] = (v.get("y_v_mps", (0, 0.0))[0], -s * x_v + c * y_v)
        if self.map.imu_attitude is not None:
            if self._tilt is None:
                return None
            a_x, a_y = level_accelerations(
                v.get("x_a_mps2", (0, 0.0))[1], v.get("y_a_mps2", (0, 0.0))[1], *self._tilt
            )
            for name, value in (("x_a_mps2", a_x), ("y_a_mps2", a_y)):
                if name in v:
                    v[name] = (v[name][0], float(value))
        if moved:
            a_x, a_y = at_cg(v.get("x_a_mps2", (0, 0.0))[1], v.get("y_a_mps2", (0, 0.0))[1],
                             v["yaw_rate_radps"][1], r_dot, self.map.imu_position_m)  # fmt: skip
            for name, value in (("x_a_mps2", a_x), ("y_a_mps2", a_y)):
                if name in v:
                    v[name] = (v[name][0], float(value))
        twist, steering = (_record(t, v, None) for t in _PARTNERS)
        return twist, steering, _record(topics.IMU, v, stamp)


def _record(topic: str, values: dict[str, tuple[int, float]], stamp: int | None) -> Any:
    """``topic``'s fields record from the latest mapped values, stamped ``stamp`` (None:
    as the source of its first mapped channel)."""
    row = []
    for ch in registry.on_topic(topic):
        if ch.name in values:
            if stamp is None:
                stamp = values[ch.name][0]
            row.append(values[ch.name][1])
        else:
            row.append(0.0 if ch.model_input else math.nan)
    return FIELDS_RECORDS[topic](stamp if stamp is not None else 0, *row)
