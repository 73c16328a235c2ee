"""Vectorised CDR encoding and decoding of the five fixed-layout sample messages.

Why this exists: building rosbags message objects and calling ``serialize_cdr`` per
message costs about 55 µs per 400 Hz step (5 messages), and ``deserialize_cdr`` about as
much again, i.e. tens of seconds for the few hundred thousand steps of one data set.
The five messages of a step have a fixed byte layout once the frame id is known, so we
serialise whole columns at once with numpy: a template row (rosbags' own serialisation
of :func:`messages.sample_to_messages` for a zero sample, so constant fields such as
covariances come from the one field mapping) is tiled, and the varying fields are
written at their offsets. Tests check the bytes equal rosbags' ``serialize_cdr``.

Each layout names every float64 field of its message, so a channel the registry
(:mod:`.channels`) puts on any of them is encoded and decoded without a change here;
:data:`FIELD_COLUMNS` derives from the registry.

Format: XCDR1 little endian as ROS 2 uses it: a 4-byte encapsulation header
``00 01 00 00``, then the fields, each aligned to its own size counted from the end of
that header. Offsets below are "body" offsets; :class:`Layout` stores absolute ones.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from . import channels as registry
from . import topics
from .field_path import joint_of
from .messages import (
    ImuCovariances,
    JointStateShape,
    TypestoreMessages,
    imu_covariances,
    joint_state_shape,
    sample_to_messages,
)
from .sample import SENSOR_CHANNELS, GroundTruth, SampleArrays, SensorNoiseSigma, VehicleSample

ENCAPSULATION_BYTES: Final = 4
ByteRows = npt.NDArray[np.uint8]
"""2-D uint8 array, one serialised message (encapsulation header included) per row."""


@dataclass(frozen=True)
class Layout:
    """Byte layout of one message type with a given frame-id length.

    Attributes:
        msgtype: ROS 2 type name.
        size: bytes per message, encapsulation header included.
        fields: attribute path -> (absolute offset, little-endian numpy dtype) of every
            field that varies from step to step.
        checks: (absolute offset, bytes) a message must hold to have this layout
            (string lengths, sequence counts, fixed strings); padding is not checked.
    """

    msgtype: str
    size: int
    fields: Mapping[str, tuple[int, np.dtype[Any]]]
    checks: tuple[tuple[int, bytes], ...]

    def matches(self, rows: ByteRows) -> bool:
        """True when every row has this layout and holds the structural bytes.

        Rows may be up to 7 bytes longer: Fast-CDR (rclpy, ``ros2 bag record``) pads the
        end of a message to 8-byte alignment, rosbags does not.
        """
        if rows.ndim != 2 or not 0 <= rows.shape[1] - self.size < 8:
            return False
        for offset, expected in self.checks:
            want = np.frombuffer(expected, dtype=np.uint8)
            if not np.array_equal(
                rows[:, offset : offset + len(expected)],
                np.broadcast_to(want, (rows.shape[0], len(expected))),
            ):
                return False
        return True

    def read(self, rows: ByteRows, name: str) -> npt.NDArray[Any]:
        """Column ``name`` of every row (a copy in native byte order)."""
        offset, dtype = self.fields[name]
        raw = np.ascontiguousarray(rows[:, offset : offset + dtype.itemsize])
        return raw.view(dtype).reshape(-1).astype(dtype.newbyteorder("="))

    def write(self, rows: ByteRows, name: str, values: npt.ArrayLike) -> None:
        """Write column ``name`` into every row in place."""
        offset, dtype = self.fields[name]
        data = np.asarray(values, dtype=dtype).reshape(-1, 1).view(np.uint8)
        rows[:, offset : offset + dtype.itemsize] = data


class _LayoutBuilder:
    """Walks a message definition, tracking CDR alignment."""

    def __init__(self, msgtype: str) -> None:
        self.msgtype = msgtype
        self.pos = 0  # body offset
        self.fields: dict[str, tuple[int, np.dtype[Any]]] = {}
        self.checks: list[tuple[int, bytes]] = []

    def _primitive(self, dtype: str, name: str | None) -> None:
        dt = np.dtype(dtype)
        self.pos = -(-self.pos // dt.itemsize) * dt.itemsize
        if name is not None:
            self.fields[name] = (ENCAPSULATION_BYTES + self.pos, dt)
        self.pos += dt.itemsize

    def f8(self, *names: str | None) -> None:
        for name in names:
            self._primitive("<f8", name)

    def u32(self, value: int) -> None:
        self._primitive("<u4", None)
        self.checks.append((ENCAPSULATION_BYTES + self.pos - 4, struct.pack("<I", value)))

    def string(self, text: str | None, length: int) -> None:
        """A string of ``length`` bytes plus NUL; ``text`` None: content not checked."""
        self.u32(length + 1)
        if text is not None:
            self.checks.append((ENCAPSULATION_BYTES + self.pos, text.encode() + b"\0"))
        self.pos += length + 1

    def header(self, frame_id_len: int) -> None:
        self._primitive("<i4", "header.stamp.sec")
        self._primitive("<u4", "header.stamp.nanosec")
        self.string(None, frame_id_len)

    def vector3(self, prefix: str) -> None:
        self.f8(*(f"{prefix}.{axis}" for axis in "xyz"))

    def covariance(self, name: str) -> None:
        self.f8(*(f"{name}[{i}]" for i in range(9)))

    def build(self) -> Layout:
        return Layout(self.msgtype, ENCAPSULATION_BYTES + self.pos, self.fields, tuple(self.checks))


def imu_layout(frame_id_len: int) -> Layout:
    """sensor_msgs/Imu: every float64 field, by its attribute path."""
    b = _LayoutBuilder(topics.IMU_TYPE)
    b.header(frame_id_len)
    b.f8(*(f"orientation.{axis}" for axis in "xyzw"))
    b.covariance("orientation_covariance")
    b.vector3("angular_velocity")
    b.covariance("angular_velocity_covariance")
    b.vector3("linear_acceleration")
    b.covariance("linear_acceleration_covariance")
    return b.build()


def twist_stamped_layout(frame_id_len: int) -> Layout:
    """geometry_msgs/TwistStamped: linear and angular x, y, z."""
    b = _LayoutBuilder(topics.TWIST_STAMPED_TYPE)
    b.header(frame_id_len)
    b.vector3("twist.linear")
    b.vector3("twist.angular")
    return b.build()


def joint_state_layout(frame_id_len: int, shape: JointStateShape | None = None) -> Layout:
    """sensor_msgs/JointState with exactly the contract's joints (``steering_rack``) and
    arrays (position and velocity; effort empty): ``shape``, default the registry's."""
    shape = shape if shape is not None else joint_state_shape()
    n = len(shape.joints)
    b = _LayoutBuilder(topics.JOINT_STATE_TYPE)
    b.header(frame_id_len)
    b.u32(n)
    for joint in shape.joints:
        b.string(joint, len(joint))
    for array in ("position", "velocity", "effort"):
        used = array in shape.arrays
        b.u32(n if used else 0)
        if used:
            b.f8(*(f"{array}[{i}]" for i in range(n)))
    return b.build()


def float64_layout() -> Layout:
    """std_msgs/Float64."""
    b = _LayoutBuilder(topics.FLOAT64_TYPE)
    b.f8("data")
    return b.build()


def layout_for(topic: str, frame_id_len: int = len(topics.BASE_FRAME)) -> Layout:
    """The fixed layout of a sample topic's messages."""
    if topic == topics.IMU:
        return imu_layout(frame_id_len)
    if topic in (topics.TWIST, topics.GROUND_TRUTH_TWIST):
        return twist_stamped_layout(frame_id_len)
    if topic == topics.STEERING:
        return joint_state_layout(frame_id_len)
    if topic == topics.GROUND_TRUTH_SIDESLIP:
        return float64_layout()
    msg = f"cdr.layout_for: {topic!r} is not a fixed-layout sample topic"
    raise KeyError(msg)


def layout_field(path: str) -> str:
    """A registry field path as the fixed layout names it: a joint by its index in the
    contract's JointState (``position[steering_rack]`` → ``position[0]``)."""
    joint = joint_of(path)
    if joint is None:
        return path
    index = joint_state_shape().joints.index(joint)
    return path.replace(f"[{joint}]", f"[{index}]")


# --- encoding ------------------------------------------------------------------------------------

FIELD_COLUMNS: Final[dict[str, tuple[tuple[str, str], ...]]] = {
    topic: tuple((layout_field(ch.field), ch.name) for ch in registry.on_topic(topic))
    for topic in (topics.IMU, topics.TWIST, topics.STEERING, topics.GROUND_TRUTH_TWIST)
}
"""Per stamped sample topic: (message field path, :class:`SampleArrays` column) pairs.

The registry's mapping (:mod:`.channels`), as :func:`messages.sample_to_messages`
uses it, in the form the byte codec needs; the test that compares our bytes with
rosbags' guards the pairing.
"""


class SampleEncoder:
    """Serialises :class:`SampleArrays` into the CDR bytes of every sample topic at once."""

    def __init__(self, sigma: SensorNoiseSigma, factory: TypestoreMessages | None = None) -> None:
        self.factory = factory if factory is not None else TypestoreMessages()
        self.covariances: ImuCovariances = imu_covariances(sigma)
        zero = VehicleSample(
            stamp_ns=0,
            truth=GroundTruth(0.0, 0.0, 0.0),
            **dict.fromkeys(SENSOR_CHANNELS, 0.0),
        )
        typestore = self.factory.typestore
        self.templates: dict[str, npt.NDArray[np.uint8]] = {}
        self.layouts: dict[str, Layout] = {}
        for topic, msg in sample_to_messages(zero, self.factory, sigma, self.covariances).items():
            raw = np.frombuffer(bytes(typestore.serialize_cdr(msg, msg.__msgtype__)), np.uint8)
            layout = layout_for(topic)
            if not layout.matches(raw.reshape(1, -1)):  # guards the layout code itself
                msg_ = f"cdr: layout of {topic} does not match rosbags serialisation"
                raise AssertionError(msg_)
            self.templates[topic], self.layouts[topic] = raw, layout

    def encode(self, arrays: SampleArrays) -> dict[str, ByteRows]:
        """Topic -> (n, size) byte rows; ground-truth topics only when arrays have truth."""
        n = len(arrays)
        sec, nanosec = np.divmod(arrays.stamp_ns, 1_000_000_000)
        if n and (sec.min() < -(2**31) or sec.max() >= 2**31):
            msg = "cdr.encode: a stamp does not fit builtin_interfaces/Time.sec (int32)"
            raise OverflowError(msg)
        out: dict[str, ByteRows] = {}
        wanted = topics.SAMPLE_TOPICS if arrays.has_truth else topics.SENSOR_TOPICS
        for topic in wanted:
            layout = self.layouts[topic]
            rows = np.tile(self.templates[topic], (n, 1))
            if "header.stamp.sec" in layout.fields:
                layout.write(rows, "header.stamp.sec", sec)
                layout.write(rows, "header.stamp.nanosec", nanosec)
            if topic == topics.GROUND_TRUTH_SIDESLIP:
                layout.write(rows, "data", arrays.beta_rad())
            for field, column in FIELD_COLUMNS.get(topic, ()):
                layout.write(rows, field, getattr(arrays, column))
            out[topic] = rows
        return out


# --- decoding -------------------------------------------------------------------------------------


def stack_rows(raws: Sequence[bytes | memoryview]) -> ByteRows | None:
    """Messages of equal length as one (n, size) array; None when lengths differ."""
    if not raws:
        return np.zeros((0, 0), dtype=np.uint8)
    size = len(raws[0])
    if any(len(r) != size for r in raws):
        return None
    return np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(len(raws), size)


def decode_columns(
    topic: str, rows: ByteRows, fields: Sequence[str] | None = None
) -> dict[str, npt.NDArray[Any]] | None:
    """Decode stacked messages of a sample topic into named columns.

    Returns ``stamp_ns`` (int64, stamped types only) and ``fields`` by their attribute
    paths (default: the contract fields of :data:`FIELD_COLUMNS`, or every field of a
    topic without channels), or None when the rows do not have the fixed layout (e.g.
    a real bag with a different JointState): the caller then deserialises message by
    message.
    """
    if rows.shape[0] == 0:
        return None
    frame_len = 0
    if topic != topics.GROUND_TRUTH_SIDESLIP:
        if rows.shape[1] < 16:
            return None
        frame_len = int(np.frombuffer(rows[0, 12:16].tobytes(), "<u4")[0]) - 1
        if frame_len < 0:
            return None
    layout = layout_for(topic, frame_len)
    if not layout.matches(rows):
        return None
    if fields is None:
        pairs = FIELD_COLUMNS.get(topic)
        own = [f for f in layout.fields if not f.startswith("header.")]
        fields = [f for f, _ in pairs] if pairs else own
    out = {name: layout.read(rows, name) for name in fields}
    if "header.stamp.sec" in layout.fields:
        sec = layout.read(rows, "header.stamp.sec").astype(np.int64)
        nanosec = layout.read(rows, "header.stamp.nanosec").astype(np.int64)
        out["stamp_ns"] = sec * 1_000_000_000 + nanosec
    return out
