"""Bags recorded by any stack: which topic and field gives each channel, in our units.

A topic map (YAML) names, for every model channel and for the reference, the topic
and the field that hold it, with a scale and offset into the channel's unit and, for
a velocity given in another frame, the heading that turns it into the body frame.
:func:`.topic_map_read.read_mapped_bag` reads a bag through it into the same
:class:`~sideslip_msgs_py.sample.SampleArrays` as :func:`~sideslip_msgs_py.bag.read_bag`
gives for our own topics, so that training and evaluation never see the difference.
Units and frames are converted here, once::

    clock: y_a_mps2            # one sample per message of this channel's topic (default)
    channels:
      x_a_mps2:       {topic: /imu/data, field: linear_acceleration.x}
      y_a_mps2:       {topic: /imu/data, field: linear_acceleration.y}
      yaw_rate_radps: {topic: /imu/data, field: angular_velocity.z}
      x_v_mps:        {topic: /odom, field: twist.twist.linear.x}      # nav_msgs/Odometry
      y_v_mps:        {topic: /odom, field: twist.twist.linear.y}
      # a steering-wheel angle [deg] as rack travel [m]: deg → rad, times the car's
      # rack travel per steering-wheel radian
      stl_m:          {topic: /steering, field: data, scale: 0.000262}
    reference:                 # optional: beta_rad, or v_x_mps and v_y_mps
      v_x_mps: {topic: /ins/velocity, field: vector.x}
      v_y_mps: {topic: /ins/velocity, field: vector.y}
      # the INS gives east/north velocity: rotate it by the car's yaw into the body
      heading: {topic: /ins/odometry, field: pose.pose.orientation, kind: quaternion}
      # where on the car the reference measures, from the CG [m] (x forward, y left):
      # its velocity is moved to the CG with the yaw rate, v_cg = v_P − r × p
      position_m: [1.2, 0.0]
    imu:                       # optional: an accelerometer in the body frame, gravity in it
      frame: body              # (REP 145's sensor_msgs/Imu); level (default): gravity-free
      attitude: {topic: /imu/data, field: orientation}   # its roll and pitch take it out
      position_m: [0.8, 0.0]   # where the IMU is, from the CG [m]: its lever arm is taken out

Fields are dotted attribute paths of the message (``twist.twist.linear.x``); an index
selects an array element by position (``position[0]``) or a ``JointState`` joint by
name (``position[steering_rack]``). A ``heading`` is a quaternion (``kind:
quaternion``, its yaw is used) or a yaw angle in radians (``kind: yaw_rad``); the
inputs' velocity can take one too (``channels: {heading: ...}``). Samples are formed on
the clock topic's stamps; every other channel takes its latest value at or before that
stamp (as :func:`~sideslip_msgs_py.bag.read_bag` does). Stamps come from
``header.stamp`` where a message has one, else from the bag's receive (log) time, and
the report says so. Missing channels (``y_v_mps`` for a car without a lateral velocity
sensor) are NaN: the ``measurable`` features do not read them.

The models estimate β at the centre of gravity, where the simulator gives it. A
reference measured elsewhere (an INS's antenna or an optical sensor on the bumper)
differs by r·x/v: 1.7° at a yaw rate of 0.3 rad/s, 20 m/s and 2 m ahead of the CG,
far more than the models' errors; ``reference.position_m`` moves it to the CG with the
mapped yaw rate.

The models' accelerations are the CG's in the horizontal frame, free of gravity, as the
simulator gives them. A strapdown IMU reads gravity through the body's roll and pitch:
in a turn its Y_a is 5–15 % more than a_y, which made every UKF-anchored model about ten
times worse on the held-out benchmark (docs/evaluation/imu-mounting). ``imu.frame:
body`` with an ``attitude`` (an orientation quaternion: an AHRS's, an INS's) turns each
sample back into the level frame (:mod:`.imu_frame`). An IMU away from the CG reads
the lever arm of the yaw motion too (ṙ·x on Y_a: 0.8 m ahead of the CG made the
UKF-anchored models 5–7× worse); ``imu.position_m`` takes it out with the mapped yaw
rate.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from . import topics
from .features import CHANNELS

REFERENCE_KEYS: Final = ("beta_rad", "v_x_mps", "v_y_mps")
MAX_LEVER_ARM_M: Final = 10.0
"""A reference further from the CG than this [m] is refused as a typo (no car is longer
than twice this)."""
_HEADING_KINDS: Final = ("quaternion", "yaw_rad")
IMU_FRAMES: Final = ("level", "body")


def contract_topic_map() -> dict[str, Any]:
    """The contract's own topics (:mod:`.topics`) as a topic map (a fresh mapping, with
    each topic's type, so that the node can subscribe to it too): a start for a map that
    scales a channel or names the IMU's mounting on our topics."""

    def source(topic: str, field: str) -> dict[str, str]:
        return {"topic": topic, "field": field, "type": topics.TOPIC_TYPES[topic]}

    return {
        "channels": {
            "x_a_mps2": source(topics.IMU, "linear_acceleration.x"),
            "y_a_mps2": source(topics.IMU, "linear_acceleration.y"),
            "yaw_rate_radps": source(topics.IMU, "angular_velocity.z"),
            "x_v_mps": source(topics.TWIST, "twist.linear.x"),
            "y_v_mps": source(topics.TWIST, "twist.linear.y"),
            "stl_m": source(topics.STEERING, f"position[{topics.STEERING_JOINT}]"),
        },
        "reference": {"beta_rad": source(topics.GROUND_TRUTH_SIDESLIP, "data")},
    }


class TopicMapError(ValueError):
    """A topic map that cannot be used (the message names the file and the key)."""


@dataclass(frozen=True)
class FieldSource:
    """One value: ``field`` of the messages on ``topic``, times ``scale`` plus ``offset``;
    ``type`` (e.g. ``nav_msgs/msg/Odometry``) is needed live only (a bag records it)."""

    topic: str
    field: str
    scale: float = 1.0
    offset: float = 0.0
    type: str | None = None


@dataclass(frozen=True)
class HeadingSource:
    """The car's yaw [rad] in the frame of a velocity: a quaternion or a yaw angle."""

    topic: str
    field: str
    kind: str = "quaternion"
    type: str | None = None


@dataclass(frozen=True)
class AttitudeSource:
    """The body's orientation (a quaternion field: its roll and pitch are used), for an
    accelerometer that reads in the body frame."""

    topic: str
    field: str
    type: str | None = None


@dataclass(frozen=True)
class TopicMap:
    """Where each channel and the reference come from (see the module docstring)."""

    channels: dict[str, FieldSource]
    reference: dict[str, FieldSource] = field(default_factory=dict)
    clock: str = "y_a_mps2"
    velocity_heading: HeadingSource | None = None
    reference_heading: HeadingSource | None = None
    source: str = "<topic map>"
    reference_position_m: tuple[float, float] = (0.0, 0.0)
    """Where the reference measures, from the CG [m], body frame (x forward, y left)."""
    imu_frame: str = "level"
    """``level``: the mapped accelerations are the contract's (gravity-free, horizontal);
    ``body``: specific force in the body frame, levelled with :attr:`imu_attitude`."""
    imu_attitude: AttitudeSource | None = None
    imu_position_m: tuple[float, float] = (0.0, 0.0)
    """Where the IMU is, from the CG [m], body frame (x forward, y left)."""

    @classmethod
    def load(cls, path: str | Path) -> TopicMap:
        """Read and check a topic map file (raises :class:`TopicMapError`)."""
        import yaml

        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text(encoding="utf-8"))
        except (OSError, yaml.YAMLError) as err:
            raise TopicMapError(f"{path}: cannot read the topic map: {err}") from None
        return cls.from_dict(data, str(path))

    @classmethod
    def from_dict(cls, data: Any, source: str = "<topic map>") -> TopicMap:
        if not isinstance(data, Mapping):
            raise TopicMapError(f"{source}: expected a mapping with 'channels'")
        unknown = set(data) - {"channels", "reference", "clock", "imu"}
        if unknown:
            raise TopicMapError(f"{source}: unknown key(s) {sorted(unknown)}")
        raw_channels = dict(data.get("channels") or {})
        velocity_heading = _heading(raw_channels.pop("heading", None), source, "channels")
        channels = {
            name: _source(spec, source, f"channels.{name}") for name, spec in raw_channels.items()
        }
        bad = sorted(set(channels) - set(CHANNELS))  # (other channels: derived or NaN)
        if bad:
            raise TopicMapError(f"{source}: unknown channel(s) {bad}; channels: {list(CHANNELS)}")
        raw_reference = dict(data.get("reference") or {})
        reference_heading = _heading(raw_reference.pop("heading", None), source, "reference")
        position = _position(raw_reference.pop("position_m", None), source)
        reference = {
            name: _source(spec, source, f"reference.{name}") for name, spec in raw_reference.items()
        }
        bad = sorted(set(reference) - set(REFERENCE_KEYS))
        if bad:
            raise TopicMapError(f"{source}: unknown reference key(s) {bad}; use {REFERENCE_KEYS}")
        if reference and not (
            set(reference) == {"beta_rad"} or set(reference) == {"v_x_mps", "v_y_mps"}
        ):
            raise TopicMapError(
                f"{source}: reference must be beta_rad, or v_x_mps and v_y_mps together"
            )
        if reference_heading is not None and "v_x_mps" not in reference:
            raise TopicMapError(f"{source}: reference.heading needs reference v_x_mps, v_y_mps")
        if position != (0.0, 0.0) and "yaw_rate_radps" not in channels:
            raise TopicMapError(
                f"{source}: reference.position_m needs the yaw_rate_radps channel (the "
                "reference is moved to the CG with it)"
            )
        if velocity_heading is not None and not {"x_v_mps", "y_v_mps"} <= set(channels):
            raise TopicMapError(f"{source}: channels.heading needs x_v_mps and y_v_mps")
        clock = str(data.get("clock", "y_a_mps2"))
        if clock not in channels:
            raise TopicMapError(f"{source}: clock {clock!r} is not one of the mapped channels")
        frame, attitude, imu_position = _imu(data.get("imu"), source, channels)
        return cls(
            channels,
            reference,
            clock,
            velocity_heading,
            reference_heading,
            source,
            position,
            frame,
            attitude,
            imu_position,
        )

    @property
    def topics(self) -> set[str]:
        sources = [*self.channels.values(), *self.reference.values()]
        headings = [h for h in (self.velocity_heading, self.reference_heading) if h]
        attitude = {self.imu_attitude.topic} if self.imu_attitude else set()
        return {s.topic for s in sources} | {h.topic for h in headings} | attitude

    def input_types(self) -> dict[str, str]:
        """Message type of every topic the inputs read (channels and their heading), for
        subscribing live. Raises :class:`TopicMapError` for a topic without a ``type``
        or with two."""
        sources: list[FieldSource | HeadingSource | AttitudeSource] = list(self.channels.values())
        if self.velocity_heading is not None:
            sources.append(self.velocity_heading)
        if self.imu_attitude is not None:
            sources.append(self.imu_attitude)
        types: dict[str, set[str]] = {}
        for src in sources:
            types.setdefault(src.topic, set())
            if src.type:
                types[src.topic].add(src.type)
        missing = sorted(t for t, ts in types.items() if not ts)
        if missing:
            raise TopicMapError(
                f"{self.source}: live input needs the message type of {missing} "
                "(add e.g. type: sensor_msgs/msg/Imu to each of their entries)"
            )
        two = sorted(t for t, ts in types.items() if len(ts) > 1)
        if two:
            raise TopicMapError(f"{self.source}: two message types given for {two}")
        return {t: ts.pop() for t, ts in types.items()}


def _source(spec: Any, source: str, key: str) -> FieldSource:
    if not isinstance(spec, Mapping) or not {"topic", "field"} <= set(spec):
        raise TopicMapError(f"{source}: {key} needs 'topic' and 'field'")
    unknown = set(spec) - {"topic", "field", "scale", "offset", "type"}
    if unknown:
        raise TopicMapError(f"{source}: {key}: unknown key(s) {sorted(unknown)}")
    try:
        scale, offset = float(spec.get("scale", 1.0)), float(spec.get("offset", 0.0))
    except (TypeError, ValueError):
        raise TopicMapError(f"{source}: {key}: scale and offset must be numbers") from None
    if not (math.isfinite(scale) and math.isfinite(offset)) or scale == 0.0:
        raise TopicMapError(f"{source}: {key}: scale must be finite and non-zero")
    kind = spec.get("type")
    return FieldSource(
        str(spec["topic"]), str(spec["field"]), scale, offset, None if kind is None else str(kind)
    )


def _position(spec: Any, source: str, key: str = "reference.position_m") -> tuple[float, float]:
    if spec is None:
        return (0.0, 0.0)
    try:
        if isinstance(spec, str | Mapping):  # "12" would iterate as 1, 2
            raise TypeError
        x, y = (float(v) for v in spec)
    except (TypeError, ValueError):
        raise TopicMapError(
            f"{source}: {key} must be [x, y] in metres from the CG, got {spec!r}"
        ) from None
    if not all(math.isfinite(v) and abs(v) <= MAX_LEVER_ARM_M for v in (x, y)):
        raise TopicMapError(
            f"{source}: {key} {spec!r}: each must be finite and within "
            f"±{MAX_LEVER_ARM_M:g} m of the CG"
        )
    return (x, y)


def _heading(spec: Any, source: str, where: str) -> HeadingSource | None:
    if spec is None:
        return None
    if not isinstance(spec, Mapping) or not {"topic", "field"} <= set(spec):
        raise TopicMapError(f"{source}: {where}.heading needs 'topic' and 'field'")
    kind = str(spec.get("kind", "quaternion"))
    if kind not in _HEADING_KINDS:
        raise TopicMapError(f"{source}: {where}.heading kind must be one of {_HEADING_KINDS}")
    msg_type = spec.get("type")
    return HeadingSource(
        str(spec["topic"]), str(spec["field"]), kind, None if msg_type is None else str(msg_type)
    )


def _imu(
    spec: Any, source: str, channels: Mapping[str, FieldSource]
) -> tuple[str, AttitudeSource | None, tuple[float, float]]:
    """The ``imu`` block: the accelerometer's frame, for ``body`` the attitude, and the
    IMU's position."""
    if spec is None:
        return "level", None, (0.0, 0.0)
    if not isinstance(spec, Mapping):
        raise TopicMapError(f"{source}: imu must be a mapping with 'frame' (and 'attitude')")
    unknown = set(spec) - {"frame", "attitude", "position_m"}
    if unknown:
        raise TopicMapError(f"{source}: imu: unknown key(s) {sorted(unknown)}")
    position = _position(spec.get("position_m"), source, "imu.position_m")
    if position != (0.0, 0.0) and "yaw_rate_radps" not in channels:
        raise TopicMapError(
            f"{source}: imu.position_m needs the yaw_rate_radps channel (the lever arm is "
            "taken out with it)"
        )
    frame = str(spec.get("frame", "level"))
    if frame not in IMU_FRAMES:
        raise TopicMapError(f"{source}: imu.frame {frame!r}: must be one of {IMU_FRAMES}")
    raw = spec.get("attitude")
    if frame == "level":
        if raw is not None:
            raise TopicMapError(
                f"{source}: imu.attitude is only read with imu.frame: body (a level "
                "accelerometer has no gravity to take out)"
            )
        return frame, None, position
    if raw is None:
        raise TopicMapError(
            f"{source}: imu.frame: body needs imu.attitude (an orientation quaternion whose "
            "roll and pitch take gravity out of the accelerations)"
        )
    if not isinstance(raw, Mapping) or not {"topic", "field"} <= set(raw):
        raise TopicMapError(f"{source}: imu.attitude needs 'topic' and 'field'")
    bad = set(raw) - {"topic", "field", "type"}
    if bad:
        raise TopicMapError(f"{source}: imu.attitude: unknown key(s) {sorted(bad)}")
    if not {"x_a_mps2", "y_a_mps2"} & set(channels):
        raise TopicMapError(f"{source}: imu.frame: body but no x_a_mps2 or y_a_mps2 is mapped")
    msg_type = raw.get("type")
    attitude = AttitudeSource(
        str(raw["topic"]), str(raw["field"]), None if msg_type is None else str(msg_type)
    )
    return frame, attitude, position


# --- reading ----------------------------------------------------------------------------------


def heading_yaw(value: Any, kind: str) -> float:
    """The car's yaw [rad] from a heading field: a quaternion or a yaw angle."""
    if kind == "yaw_rad":
        return float(value)
    x, y, z, w = float(value.x), float(value.y), float(value.z), float(value.w)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
