"""Reading a bag through a topic map (:mod:`.topic_map`): the samples in our channels and
units, the reference in the body frame at the CG. Units and frames are converted here,
once, so that training and evaluation never see the difference from our own bags."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from . import channels as registry
from .bag_raw import open_raw_bag
from .errors import BagError, MissingTopicError
from .features import CHANNELS
from .field_path import field_value
from .imu_frame import at_cg, level_accelerations, roll_pitch, yaw_accelerations
from .message_fields import stamp_ns
from .sample import SampleArrays
from .topic_map import AttitudeSource, FieldSource, HeadingSource, TopicMap, heading_yaw


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
    if topic_map.imu_attitude is not None:
        _level(cols, topic_map.imu_attitude, decoded, stamps, path)
        notes.append(
            f"accelerations read in the body frame: levelled with the roll and pitch of "
            f"{topic_map.imu_attitude.topic}"
        )
    if topic_map.imu_position_m != (0.0, 0.0):
        _to_cg(cols, topic_map.imu_position_m, stamps)
        x, y = topic_map.imu_position_m
        notes.append(f"IMU at ({x:g}, {y:g}) m from the CG: its lever arm taken out")
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
    if truth and topic_map.reference_position_m != (0.0, 0.0):
        x, y = topic_map.reference_position_m
        r = cols["yaw_rate_radps"]
        # A rigid body: v_P = v_cg + r ẑ × p, so v_cg = v_P − r·(−y, x).
        truth["truth_v_x_mps"] = truth["truth_v_x_mps"] + r * y
        truth["truth_v_y_mps"] = truth["truth_v_y_mps"] - r * x
        notes.append(
            f"reference measured at ({x:g}, {y:g}) m from the CG: moved to the CG with the yaw rate"
        )
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


def _level(
    cols: dict[str, npt.NDArray[np.float64]],
    attitude: AttitudeSource,
    decoded: Mapping[str, list[tuple[int, Any]]],
    stamps: npt.NDArray[np.int64],
    path: Path,
) -> None:
    """The mapped accelerations, read in the body frame, in the level frame (in place)."""
    messages = decoded[attitude.topic]

    def angle(k: int) -> npt.NDArray[np.float64]:
        series = _series(messages, attitude.field, attitude.topic, path, lambda q: roll_pitch(q)[k])
        return _at(series, stamps)

    roll, pitch = angle(0), angle(1)
    zeros = np.zeros(stamps.shape)
    a_x, a_y = level_accelerations(
        cols.get("x_a_mps2", zeros), cols.get("y_a_mps2", zeros), roll, pitch
    )
    for name, levelled in (("x_a_mps2", a_x), ("y_a_mps2", a_y)):
        if name in cols:
            cols[name] = levelled


def _to_cg(
    cols: dict[str, npt.NDArray[np.float64]],
    position_m: tuple[float, float],
    stamps: npt.NDArray[np.int64],
) -> None:
    """The mapped level accelerations of an IMU at ``position_m``, at the CG (in place)."""
    r = cols["yaw_rate_radps"]
    zeros = np.zeros(stamps.shape)
    a_x, a_y = at_cg(
        cols.get("x_a_mps2", zeros), cols.get("y_a_mps2", zeros), r,
        yaw_accelerations(stamps, r), position_m,
    )  # fmt: skip
    for name, moved in (("x_a_mps2", a_x), ("y_a_mps2", a_y)):
        if name in cols:
            cols[name] = moved


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
