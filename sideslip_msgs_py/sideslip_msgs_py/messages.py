"""Field mapping between :class:`VehicleSample` and the standard ROS 2 messages.

Written once, used with two message back-ends that share field names:

* :class:`RclpyMessages`: the rosidl-generated classes (``sensor_msgs.msg.Imu``, ...) a
  node publishes; imported lazily, so this module imports without ROS installed.
* :class:`TypestoreMessages`: the dataclasses of rosbags' Jazzy typestore, which the
  bag writer serialises.

Every message is built with all fields given explicitly (rosbags dataclasses have no
defaults), and read back through attribute access only, so both back-ends go through
the same lines of code.

Which field carries which channel comes from the registry (:mod:`.channels`): a message
is built as a skeleton per topic (the constant fields: orientation, covariances, joint
names, zeros), then each channel's value is written at its field path; reading takes
the same paths. So a channel added to the registry on an existing topic is published,
read and recorded without a change here.

Mapping (body frame at the CG, REP-103, SI units; all messages of one step carry the
same ``header.stamp`` and ``frame_id = 'base_link'``):

==============================  ===========================================================
``/vehicle/imu`` (Imu)          linear_acceleration.x = X_a, .y = Y_a [m/s²], .z = 0;
                                angular_velocity.z = ψ̇ [rad/s], .x = .y = 0;
                                orientation = identity with orientation_covariance[0] = -1
                                ("no orientation estimate", sensor_msgs/Imu convention).
``/vehicle/twist``              twist.linear.x = X_v, .y = Y_v [m/s]; all else 0.
``/vehicle/steering``           name = ['steering_rack'], position = [STL m],
                                velocity = [STL rate m/s], effort = [].
``/vehicle/ground_truth/twist`` twist.linear.x = v_x, .y = v_y [m/s], angular.z = ψ̇ [rad/s].
``/vehicle/ground_truth/        data = β = atan2(v_y, v_x) [rad].
sideslip`` (Float64)
==============================  ===========================================================

IMU covariances (row-major 3×3, diagonal only): the channels we provide (the registry's
IMU channels: gyro z; accel x and y) carry σ² from :class:`SensorNoiseSigma`. The
channels we do not provide (gyro x, y; accel z) are published as 0.0 with variance
:data:`UNMEASURED_VARIANCE` (1e6), so a fusion node that reads the covariance gives
them no weight instead of trusting a fake zero.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any, Final, NamedTuple, Protocol

import numpy as np
import numpy.typing as npt

from . import channels as registry
from . import topics
from .errors import MessageFieldError
from .field_path import joint_of, parse, set_field
from .message_fields import (
    FIELDS_RECORDS,
    NS_PER_S,
    GroundTruthFields,
    ImuFields,
    SteeringFields,
    TwistFields,
    channel_values,
    ground_truth_fields,
    imu_fields,
    stamp_ns,
    steering_fields,
    twist_fields,
)
from .sample import SensorNoiseSigma, VehicleSample

UNMEASURED_VARIANCE: Final = 1.0e6
"""Variance put on IMU channels the contract does not provide (gyro x/y, accel z)."""


class MessageFactory(Protocol):
    """The message classes one back-end provides (constructors take keyword fields)."""

    Imu: Any
    TwistStamped: Any
    JointState: Any
    Float64: Any
    Header: Any
    Time: Any
    Vector3: Any
    Quaternion: Any
    Twist: Any
    TwistWithCovariance: Any
    TwistWithCovarianceStamped: Any
    DiagnosticArray: Any
    DiagnosticStatus: Any
    KeyValue: Any
    Clock: Any

    def diagnostic_level(self, level: int) -> Any:
        """DiagnosticStatus.level in the back-end's representation of ROS ``byte``."""
        ...


class RclpyMessages:
    """rosidl-generated message classes, as a node publishes them (needs ROS installed)."""

    def __init__(self) -> None:
        # Imported here so that the package imports on machines without ROS.
        from builtin_interfaces.msg import Time
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
        from geometry_msgs.msg import (
            Quaternion,
            Twist,
            TwistStamped,
            TwistWithCovariance,
            TwistWithCovarianceStamped,
            Vector3,
        )
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import Imu, JointState
        from std_msgs.msg import Float64, Header

        self.Imu = Imu
        self.TwistStamped = TwistStamped
        self.JointState = JointState
        self.Float64 = Float64
        self.Header = Header
        self.Time = Time
        self.Vector3 = Vector3
        self.Quaternion = Quaternion
        self.Twist = Twist
        self.TwistWithCovariance = TwistWithCovariance
        self.TwistWithCovarianceStamped = TwistWithCovarianceStamped
        self.DiagnosticArray = DiagnosticArray
        self.DiagnosticStatus = DiagnosticStatus
        self.KeyValue = KeyValue
        self.Clock = Clock

    def diagnostic_level(self, level: int) -> bytes:
        # rosidl maps the ROS `byte` type to a 1-byte bytes object.
        return bytes([level])


class TypestoreMessages:
    """Message dataclasses of a rosbags typestore (default: ROS 2 Jazzy)."""

    def __init__(self, typestore: Any = None) -> None:
        if typestore is None:
            from rosbags.typesys import Stores, get_typestore

            typestore = get_typestore(Stores.ROS2_JAZZY)
        self.typestore = typestore
        types = typestore.types
        self.Imu = types[topics.IMU_TYPE]
        self.TwistStamped = types[topics.TWIST_STAMPED_TYPE]
        self.JointState = types[topics.JOINT_STATE_TYPE]
        self.Float64 = types[topics.FLOAT64_TYPE]
        self.Header = types["std_msgs/msg/Header"]
        self.Time = types["builtin_interfaces/msg/Time"]
        self.Vector3 = types["geometry_msgs/msg/Vector3"]
        self.Quaternion = types["geometry_msgs/msg/Quaternion"]
        self.Twist = types["geometry_msgs/msg/Twist"]
        self.TwistWithCovariance = types["geometry_msgs/msg/TwistWithCovariance"]
        self.TwistWithCovarianceStamped = types[topics.TWIST_WITH_COVARIANCE_STAMPED_TYPE]
        self.DiagnosticArray = types[topics.DIAGNOSTIC_ARRAY_TYPE]
        self.DiagnosticStatus = types["diagnostic_msgs/msg/DiagnosticStatus"]
        self.KeyValue = types["diagnostic_msgs/msg/KeyValue"]
        self.Clock = types[topics.CLOCK_TYPE]

    def diagnostic_level(self, level: int) -> int:
        # rosbags maps the ROS `byte` type to an int.
        return int(level)


# --- covariances -----------------------------------------------------------------------------


@dataclass(frozen=True)
class ImuCovariances:
    """The three row-major 3×3 covariance arrays of an Imu message (float64[9] each)."""

    orientation: npt.NDArray[np.float64]
    angular_velocity: npt.NDArray[np.float64]
    linear_acceleration: npt.NDArray[np.float64]


def _axis_variances(vector: str, sigma: SensorNoiseSigma) -> npt.NDArray[np.float64]:
    """Diagonal 3×3 covariance of an Imu vector: σ² of the channel on each axis, else
    :data:`UNMEASURED_VARIANCE` (a channel without a noise key is exact: 0)."""
    variances = [UNMEASURED_VARIANCE] * 3
    for ch in registry.on_topic(topics.IMU):
        name, _, axis = ch.field.partition(".")
        if name == vector:
            std = 0.0 if ch.sigma is None else getattr(sigma, ch.sigma)
            variances["xyz".index(axis)] = std**2
    return np.diag(variances).ravel()


def imu_covariances(sigma: SensorNoiseSigma) -> ImuCovariances:
    """IMU covariances for the given sensor noise (see the module docstring)."""
    orientation = np.zeros(9)
    orientation[0] = -1.0  # sensor_msgs/Imu: "no orientation estimate"
    return ImuCovariances(
        orientation,
        _axis_variances("angular_velocity", sigma),
        _axis_variances("linear_acceleration", sigma),
    )


# --- sample -> messages ----------------------------------------------------------------------


def stamp_to_sec_nanosec(stamp_ns: int) -> tuple[int, int]:
    """Split integer nanoseconds into builtin_interfaces/Time (sec, nanosec)."""
    sec, nanosec = divmod(int(stamp_ns), NS_PER_S)
    if not -(2**31) <= sec < 2**31:
        msg = f"stamp {stamp_ns} ns does not fit builtin_interfaces/Time.sec (int32)"
        raise MessageFieldError(msg)
    return sec, nanosec


def header(factory: MessageFactory, stamp_ns: int, frame_id: str = topics.BASE_FRAME) -> Any:
    """A std_msgs/Header with the given stamp [ns] and frame."""
    sec, nanosec = stamp_to_sec_nanosec(stamp_ns)
    return factory.Header(stamp=factory.Time(sec=sec, nanosec=nanosec), frame_id=frame_id)


def vector3(factory: MessageFactory, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Any:
    return factory.Vector3(x=float(x), y=float(y), z=float(z))


class JointStateShape(NamedTuple):
    """The JointState the contract publishes: its joints and which arrays have values."""

    joints: tuple[str, ...]
    arrays: tuple[str, ...]
    """Of ``position``, ``velocity``, ``effort``: those with one entry per joint (the
    others are empty)."""


@cache
def joint_state_shape(topic: str = topics.STEERING) -> JointStateShape:
    """From the registry's channels on ``topic``: ``(steering_rack,)``, position and velocity."""
    paths = [ch.field for ch in registry.on_topic(topic)]
    joints = tuple(dict.fromkeys(j for p in paths if (j := joint_of(p)) is not None))
    used = {parse(p)[0].name for p in paths}
    arrays = tuple(a for a in ("position", "velocity", "effort") if a in used)
    return JointStateShape(joints, arrays)


def _skeletons(
    factory: MessageFactory, hdr: Any, cov: ImuCovariances, truth: bool
) -> dict[str, Any]:
    """The stamped sample topics' messages (ground truth only with ``truth``), with their
    constant fields and zero values."""
    joints = joint_state_shape()
    arrays = {
        a: np.zeros(len(joints.joints) if a in joints.arrays else 0, dtype=np.float64)
        for a in ("position", "velocity", "effort")
    }

    def twist() -> Any:
        return factory.TwistStamped(
            header=hdr,
            twist=factory.Twist(linear=vector3(factory), angular=vector3(factory)),
        )

    built = {
        topics.IMU: factory.Imu(
            header=hdr,
            orientation=factory.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=cov.orientation.copy(),
            angular_velocity=vector3(factory),
            angular_velocity_covariance=cov.angular_velocity.copy(),
            linear_acceleration=vector3(factory),
            linear_acceleration_covariance=cov.linear_acceleration.copy(),
        ),
        topics.TWIST: twist(),
        topics.STEERING: factory.JointState(header=hdr, name=list(joints.joints), **arrays),
    }
    if truth:
        built[topics.GROUND_TRUTH_TWIST] = twist()
    return built


def sample_to_messages(
    sample: VehicleSample,
    factory: MessageFactory,
    sigma: SensorNoiseSigma,
    covariances: ImuCovariances | None = None,
) -> dict[str, Any]:
    """The messages of one step, keyed by topic, in :data:`topics.SAMPLE_TOPICS` order.

    Sensor topics are always present; the two ground-truth topics only when
    ``sample.truth`` is set. ``covariances`` may be passed precomputed (from
    :func:`imu_covariances` of the same ``sigma``) to save work in a 400 Hz loop.
    """
    cov = covariances if covariances is not None else imu_covariances(sigma)
    truth = sample.truth
    built = _skeletons(factory, header(factory, sample.stamp_ns), cov, truth is not None)
    for ch in registry.SENSOR:
        set_field(built[ch.topic], ch.field, getattr(sample, ch.name))
    out = {topic: built[topic] for topic in topics.SENSOR_TOPICS}
    if truth is not None:
        out[topics.GROUND_TRUTH_TWIST] = built[topics.GROUND_TRUTH_TWIST]
        for ch in registry.TRUTH:
            attr = ch.name.removeprefix(registry.TRUTH_PREFIX)
            set_field(out[ch.topic], ch.field, getattr(truth, attr))
        out[topics.GROUND_TRUTH_SIDESLIP] = factory.Float64(data=truth.beta_rad)
    return out


# --- messages -> sample ------------------------------------------------------------------------


def messages_to_sample(messages: Mapping[str, Any]) -> VehicleSample:
    """A :class:`VehicleSample` from messages keyed by topic (either back-end).

    The sample takes the IMU stamp; the caller has already chosen which twist and
    steering message belong to it (the estimator aligns on the IMU stamp). Ground truth
    is read from /vehicle/ground_truth/twist when present.
    """
    missing = [t for t in topics.SENSOR_TOPICS if t not in messages]
    if missing:
        msg = f"messages_to_sample: missing sensor topic(s) {missing}"
        raise MessageFieldError(msg)
    values: dict[str, float] = {}
    for topic in topics.SENSOR_TOPICS:
        names = (ch.name for ch in registry.on_topic(topic))
        values.update(zip(names, channel_values(messages[topic], topic), strict=True))
    gt = messages.get(topics.GROUND_TRUTH_TWIST)
    return VehicleSample(
        stamp_ns=stamp_ns(messages[topics.IMU]),
        truth=ground_truth_fields(gt).truth if gt is not None else None,
        **values,
    )


__all__ = [
    "FIELDS_RECORDS",
    "NS_PER_S",
    "UNMEASURED_VARIANCE",
    "GroundTruthFields",
    "ImuCovariances",
    "ImuFields",
    "JointStateShape",
    "MessageFactory",
    "RclpyMessages",
    "SteeringFields",
    "TwistFields",
    "TypestoreMessages",
    "channel_values",
    "ground_truth_fields",
    "header",
    "imu_covariances",
    "imu_fields",
    "joint_state_shape",
    "messages_to_sample",
    "sample_to_messages",
    "stamp_ns",
    "stamp_to_sec_nanosec",
    "steering_fields",
    "twist_fields",
    "vector3",
]
