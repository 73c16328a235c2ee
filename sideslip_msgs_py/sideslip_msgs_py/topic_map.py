"""Bags recorded by any stack: which topic and field gives each channel, in our units.

A topic map (YAML) names, for every model channel and for the reference, the topic
and the field that hold it, with a scale and offset into the channel's unit and, for
a velocity given in another frame, the heading that turns it into the body frame.
:func:`read_mapped_bag` reads a bag through it into the same
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
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from . import channels as registry
from .bag_raw import open_raw_bag
from .errors import BagError, MissingTopicError
from .features import CHANNELS
from .field_path import field_value
from .message_fields import stamp_ns
from .sample import SampleArrays

REFERENCE_KEYS: Final = ("beta_rad", "v_x_mps", "v_y_mps")
_HEADING_KINDS: Final = ("quaternion", "yaw_rad")


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
class TopicMap:
    """Where each channel and the reference come from (see the module docstring)."""

    channels: dict[str, FieldSource]
    reference: dict[str, FieldSource] = field(default_factory=dict)
    clock: str = "y_a_mps2"
    velocity_heading: HeadingSource | None = None
    reference_heading: HeadingSource | None = None
    source: str = "<topic map>"

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
        unknown = set(data) - {"channels", "reference", "clock"}
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
        if velocity_heading is not None and not {"x_v_mps", "y_v_mps"} <= set(channels):
            raise TopicMapError(f"{source}: channels.heading needs x_v_mps and y_v_mps")
        clock = str(data.get("clock", "y_a_mps2"))
        if clock not in channels:
            raise TopicMapError(f"{source}: clock {clock!r} is not one of the mapped channels")
        return cls(channels, reference, clock, velocity_heading, reference_heading, source)

    @property
    def topics(self) -> set[str]:
        sources = [*self.channels.values(), *self.reference.values()]
        headings = [h for h in (self.velocity_heading, self.reference_heading) if h]
        return {s.topic for s in sources} | {h.topic for h in headings}

    def input_types(self) -> dict[str, str]:
        """Message type of every topic the inputs read (channels and their heading), for
        subscribing live. Raises :class:`TopicMapError` for a topic without a ``type``
        or with two."""
        sources: list[FieldSource | HeadingSource] = list(self.channels.values())
        if self.velocity_heading is not None:
            sources.append(self.velocity_heading)
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


# --- reading ----------------------------------------------------------------------------------


def heading_yaw(value: Any, kind: str) -> float:
    """The car's yaw [rad] from a heading field: a quaternion or a yaw angle."""
    if kind == "yaw_rad":
        return float(value)
    x, y, z, w = float(value.x), float(value.y), float(value.z), float(value.w)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


@dataclass
class _Series:
    stamp_ns: npt.NDArray[np.int64]
    values: npt.NDArray[np.float64]


def _series(
    messages: list[tuple[int, Any]], path: str, topic: str, bag: Path, convert: Any
) -> _Series:
    stamps = np.empty(len(messages), dtype=np.int64)
    values = np.empty(len(messages), dtype=np.float64)
    for i, (stamp, msg) in enumerate(messages):
        try:
            values[i] = convert(field_value(msg, path))
        except (AttributeError, KeyError, IndexError, TypeError, ValueError) as err:
            raise BagError(f"{bag}: {topic}: field {path!r}: {err}") from None
        stamps[i] = stamp
    order = np.argsort(stamps, kind="stable")
    return _Series(stamps[order], values[order])


def _at(series: _Series, stamps: npt.NDArray[np.int64]) -> npt.NDArray[np.float64]:
    """The latest value at or before each stamp (NaN before the first)."""
    idx = np.searchsorted(series.stamp_ns, stamps, side="right") - 1
    out = series.values[np.maximum(idx, 0)].copy()
    out[idx < 0] = np.nan
    return out


@dataclass(frozen=True)
class MappedBag:
    """What :func:`read_mapped_bag` read: the samples and what was not verbatim."""

    path: Path
    samples: SampleArrays
    notes: tuple[str, ...]
    truncated: bool = False


def read_mapped_bag(path: str | Path, topic_map: TopicMap) -> MappedBag:
    """Samples of a bag recorded with any topics, through ``topic_map``.

    Raises:
        MissingTopicError: a mapped topic is absent or has no message.
        BagError: a message lacks a mapped field, or cannot be decoded.
    """
    from rosbags.typesys import Stores, get_typestore

    from .bag import _deserialize

    path = Path(path)
    raw = open_raw_bag(path)
    wanted = topic_map.topics
    missing = sorted(t for t in wanted if t not in raw.topics or not raw.topics[t].count)
    if missing:
        found = sorted(t for t, info in raw.topics.items() if info.count)
        msg = f"{path}: no messages on mapped topic(s) {missing} (topics with messages: {found})"
        raise MissingTopicError(msg)
    typestore = get_typestore(Stores.ROS2_JAZZY)
    decoded: dict[str, list[tuple[int, Any]]] = {t: [] for t in wanted}
    headerless: set[str] = set()
    for m in raw.messages(wanted):
        msgtype = raw.topics[m.topic].msgtype
        try:
            msg = _deserialize(typestore, m.data, msgtype)
        except Exception as err:
            msg = f"{path}: cannot decode a {msgtype} message on {m.topic}: {err}"
            raise BagError(msg) from err
        if hasattr(msg, "header"):
            stamp = stamp_ns(msg)
        else:
            stamp = m.log_time_ns
            headerless.add(m.topic)
        decoded[m.topic].append((stamp, msg))
    notes = list(raw.notes)
    notes.extend(f"{t}: no header: stamped with the bag's receive time" for t in sorted(headerless))

    def series(src: FieldSource) -> _Series:
        s = _series(decoded[src.topic], src.field, src.topic, path, float)
        s.values = s.values * src.scale + src.offset
        return s

    clock = series(topic_map.channels[topic_map.clock])
    stamps = clock.stamp_ns
    if stamps.size > 1 and (np.diff(stamps) == 0).any():
        raise BagError(f"{path}: the clock topic has repeated stamps; samples need distinct ones")
    cols = {name: _at(series(src), stamps) for name, src in topic_map.channels.items()}
    if topic_map.velocity_heading is not None:
        cols["x_v_mps"], cols["y_v_mps"] = _to_body(
            cols["x_v_mps"], cols["y_v_mps"], topic_map.velocity_heading, decoded, stamps, path
        )
    for name in CHANNELS:
        if name not in cols:
            cols[name] = np.full(stamps.shape, np.nan)
    _derive_other_channels(cols, stamps)
    ref = topic_map.reference
    truth: dict[str, npt.NDArray[np.float64]] = {}
    if "beta_rad" in ref:
        beta = _at(series(ref["beta_rad"]), stamps)
        speed = np.where(np.isfinite(cols["x_v_mps"]), cols["x_v_mps"], 1.0)
        truth = {"truth_v_x_mps": speed, "truth_v_y_mps": speed * np.tan(beta)}
        notes.append("reference β given: its velocity is X_v · (1, tan β)")
    elif ref:
        v_x, v_y = _at(series(ref["v_x_mps"]), stamps), _at(series(ref["v_y_mps"]), stamps)
        if topic_map.reference_heading is not None:
            v_x, v_y = _to_body(v_x, v_y, topic_map.reference_heading, decoded, stamps, path)
        truth = {"truth_v_x_mps": v_x, "truth_v_y_mps": v_y}
    if truth:
        truth["truth_yaw_rate_radps"] = cols["yaw_rate_radps"]
    samples = SampleArrays(stamp_ns=stamps, **cols, **truth)
    return MappedBag(path, samples, tuple(notes), raw.truncated)


def _derive_other_channels(
    cols: dict[str, npt.NDArray[np.float64]], stamps: npt.NDArray[np.int64]
) -> None:
    """The sample columns a topic map does not give (no model input): a rate by
    differencing its channel (the rack's rate from STL), any other NaN."""
    for ch in registry.SENSOR:
        if ch.name in cols:
            continue
        if ch.rate_of is None:
            cols[ch.name] = np.full(stamps.shape, np.nan)
        elif stamps.size > 2:
            cols[ch.name] = np.gradient(cols[ch.rate_of], stamps * 1e-9)
        else:
            cols[ch.name] = np.zeros(stamps.shape)


def _to_body(
    v_x: npt.NDArray[np.float64],
    v_y: npt.NDArray[np.float64],
    heading: HeadingSource,
    decoded: Mapping[str, list[tuple[int, Any]]],
    stamps: npt.NDArray[np.int64],
    path: Path,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """A velocity in a frame where the car's yaw is ``heading``, in the body frame."""
    yaw_series = _series(
        decoded[heading.topic],
        heading.field,
        heading.topic,
        path,
        lambda v: heading_yaw(v, heading.kind),
    )
    yaw = _at(yaw_series, stamps)
    c, s = np.cos(yaw), np.sin(yaw)
    return c * v_x + s * v_y, -s * v_x + c * v_y
