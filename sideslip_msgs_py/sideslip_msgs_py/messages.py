"""Field mapping between :class:`VehicleSample` and the standard ROS 2 messages.

Written once, used with two message back-ends that share field names:

* :class:`RclpyMessages`: the rosidl-generated classes (``sensor_msgs.msg.Imu``, ...) a
  node publishes; imported lazily, so this module imports without ROS installed.
* :class:`TypestoreMessages`: the dataclasses of rosbags' Jazzy typestore, which the
  bag writer serialises.

Every message is built with all fields given explicitly (rosbags dataclasses have no
defaults), and read back through attribute access only, so both back-ends go through
the same lines of code.

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

IMU covariances (row-major 3×3, diagonal only): the channels we provide carry σ²
from :class:`SensorNoiseSigma` (gyro z; accel x and y). The channels we do not provide
(gyro x, y; accel z) are published as 0.0 with variance :data:`UNMEASURED_VARIANCE`
(1e6), so a fusion node that reads the covariance gives them no weight instead of
trusting a fake zero.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final, NamedTuple, Protocol

import numpy as np
import numpy.typing as npt

from . import topics
from .errors import MessageFieldError
from .sample import GroundTruth, SensorNoiseSigma, VehicleSample

UNMEASURED_VARIANCE: Final = 1.0e6
"""Variance put on IMU channels the contract does not provide (gyro x/y, accel z)."""

NS_PER_S: Final = 1_000_000_000


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


def imu_covariances(sigma: SensorNoiseSigma) -> ImuCovariances:
    """IMU covariances for the given sensor noise (see the module docstring)."""
    orientation = np.zeros(9)
    orientation[0] = -1.0  # sensor_msgs/Imu: "no orientation estimate"
    gyro = np.diag([UNMEASURED_VARIANCE, UNMEASURED_VARIANCE, sigma.yaw_rate_radps**2])
    var_a = sigma.acceleration_mps2**2
    accel = np.diag([var_a, var_a, UNMEASURED_VARIANCE])
    return ImuCovariances(orientation, gyro.ravel(), accel.ravel())


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


def _twist_stamped(factory: MessageFactory, hdr: Any, v_x: float, v_y: float, r: float) -> Any:
    twist = factory.Twist(linear=vector3(factory, v_x, v_y), angular=vector3(factory, z=r))
    return factory.TwistStamped(header=hdr, twist=twist)


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
    hdr = header(factory, sample.stamp_ns)
    built: dict[str, Any] = {
        topics.IMU: factory.Imu(
            header=hdr,
            orientation=factory.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=cov.orientation.copy(),
            angular_velocity=vector3(factory, z=sample.yaw_rate_radps),
            angular_velocity_covariance=cov.angular_velocity.copy(),
            linear_acceleration=vector3(factory, sample.x_a_mps2, sample.y_a_mps2),
            linear_acceleration_covariance=cov.linear_acceleration.copy(),
        ),
        topics.TWIST: _twist_stamped(factory, hdr, sample.x_v_mps, sample.y_v_mps, 0.0),
        topics.STEERING: factory.JointState(
            header=hdr,
            name=[topics.STEERING_JOINT],
            position=np.array([sample.stl_m], dtype=np.float64),
            velocity=np.array([sample.stl_rate_mps], dtype=np.float64),
            effort=np.zeros(0, dtype=np.float64),
        ),
    }
    out = {topic: built[topic] for topic in topics.SENSOR_TOPICS}
    if sample.truth is not None:
        t = sample.truth
        out[topics.GROUND_TRUTH_TWIST] = _twist_stamped(
            factory, hdr, t.v_x_mps, t.v_y_mps, t.yaw_rate_radps
        )
        out[topics.GROUND_TRUTH_SIDESLIP] = factory.Float64(data=t.beta_rad)
    return out


# --- messages -> fields ------------------------------------------------------------------------


class ImuFields(NamedTuple):
    """What the contract reads from /vehicle/imu."""

    stamp_ns: int
    x_a_mps2: float
    y_a_mps2: float
    yaw_rate_radps: float


class TwistFields(NamedTuple):
    """What the contract reads from /vehicle/twist."""

    stamp_ns: int
    x_v_mps: float
    y_v_mps: float


class SteeringFields(NamedTuple):
    """What the contract reads from /vehicle/steering (rate NaN when not published)."""

    stamp_ns: int
    stl_m: float
    stl_rate_mps: float


class GroundTruthFields(NamedTuple):
    """What the contract reads from /vehicle/ground_truth/twist."""

    stamp_ns: int
    truth: GroundTruth


def stamp_ns(msg: Any) -> int:
    """``msg.header.stamp`` as integer nanoseconds."""
    stamp = msg.header.stamp
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def imu_fields(msg: Any) -> ImuFields:
    """X_a, Y_a [m/s²] and ψ̇ [rad/s] of an Imu message of either back-end."""
    acc = msg.linear_acceleration
    return ImuFields(stamp_ns(msg), float(acc.x), float(acc.y), float(msg.angular_velocity.z))


def twist_fields(msg: Any) -> TwistFields:
    """X_v, Y_v [m/s] of a TwistStamped message of either back-end."""
    lin = msg.twist.linear
    return TwistFields(stamp_ns(msg), float(lin.x), float(lin.y))


def steering_fields(msg: Any, topic: str = topics.STEERING) -> SteeringFields:
    """STL [m] and its rate [m/s] of the ``steering_rack`` joint in a JointState.

    Raises :class:`MessageFieldError` when the joint or its position is missing. A
    missing velocity gives NaN: real steering sensors often publish position only.
    """
    names = list(msg.name)
    try:
        i = names.index(topics.STEERING_JOINT)
    except ValueError:
        msg_ = f"{topic}: JointState.name has no {topics.STEERING_JOINT!r} (names: {names})"
        raise MessageFieldError(msg_) from None
    if len(msg.position) <= i:
        msg_ = f"{topic}: JointState.position has no entry for {topics.STEERING_JOINT!r}"
        raise MessageFieldError(msg_)
    rate = float(msg.velocity[i]) if len(msg.velocity) > i else float("nan")
    return SteeringFields(stamp_ns(msg), float(msg.position[i]), rate)


def ground_truth_fields(msg: Any) -> GroundTruthFields:
    """Exact v_x, v_y [m/s] and ψ̇ [rad/s] of a ground-truth TwistStamped."""
    twist = msg.twist
    truth = GroundTruth(float(twist.linear.x), float(twist.linear.y), float(twist.angular.z))
    return GroundTruthFields(stamp_ns(msg), truth)


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
    imu = imu_fields(messages[topics.IMU])
    twist = twist_fields(messages[topics.TWIST])
    steer = steering_fields(messages[topics.STEERING])
    gt = messages.get(topics.GROUND_TRUTH_TWIST)
    return VehicleSample(
        stamp_ns=imu.stamp_ns,
        x_v_mps=twist.x_v_mps,
        y_v_mps=twist.y_v_mps,
        x_a_mps2=imu.x_a_mps2,
        y_a_mps2=imu.y_a_mps2,
        yaw_rate_radps=imu.yaw_rate_radps,
        stl_m=steer.stl_m,
        stl_rate_mps=steer.stl_rate_mps,
        truth=ground_truth_fields(gt).truth if gt is not None else None,
    )
