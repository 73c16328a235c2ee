"""A bag as another stack records it: other topic names and types, 100 Hz, a header-less
steering-wheel angle in degrees, and a GNSS/INS velocity in the east/north frame.

Written with rosbags' own message classes (not our encoder), from known body-frame
values, so a test can check that a topic map gives those values back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sideslip_msgs_py.bag import open_writer

RACK_PER_WHEEL_DEG = 0.00021  # [m of rack travel per steering-wheel degree]
GRAVITY = 9.80665  # [m/s²]

TOPIC_MAP = {
    "channels": {
        "x_a_mps2": {"topic": "/imu/data", "field": "linear_acceleration.x"},
        "y_a_mps2": {"topic": "/imu/data", "field": "linear_acceleration.y"},
        "yaw_rate_radps": {"topic": "/imu/data", "field": "angular_velocity.z"},
        "x_v_mps": {"topic": "/odom", "field": "twist.twist.linear.x"},
        "y_v_mps": {"topic": "/odom", "field": "twist.twist.linear.y"},
        "stl_m": {"topic": "/steering_wheel_deg", "field": "data", "scale": RACK_PER_WHEEL_DEG},
    },
    "reference": {
        "v_x_mps": {"topic": "/ins/velocity_enu", "field": "vector.x"},
        "v_y_mps": {"topic": "/ins/velocity_enu", "field": "vector.y"},
        "heading": {"topic": "/odom", "field": "pose.pose.orientation", "kind": "quaternion"},
    },
}


@dataclass(frozen=True)
class Truth:
    """The body-frame values the bag was made from, at the IMU stamps."""

    stamp_ns: np.ndarray
    x_v: np.ndarray
    y_v: np.ndarray
    x_a: np.ndarray
    y_a: np.ndarray
    r: np.ndarray
    stl: np.ndarray
    yaw: np.ndarray


def make_truth(n: int, rate_hz: float = 100.0, seed: int = 0) -> Truth:
    rng = np.random.default_rng(seed)
    stamps = 10**15 + np.round(np.arange(n) * 1e9 / rate_hz).astype(np.int64)
    t = (stamps - stamps[0]) * 1e-9
    r = 0.3 * np.sin(2 * math.pi * 0.4 * t + seed)
    x_v = 20.0 + 0.5 * np.sin(0.3 * t)
    y_v = 0.6 * np.sin(2 * math.pi * 0.4 * t + 0.3 + seed)
    yaw = 1.0 + np.cumsum(r) / rate_hz  # driving somewhere north-east, turning
    return Truth(
        stamp_ns=stamps,
        x_v=x_v + rng.normal(0, 0.05, n),
        y_v=y_v + rng.normal(0, 0.05, n),
        x_a=rng.normal(0, 0.1, n),
        # a_y = v̇_y + v_x·r, as on a car: the accelerometer check (sideslip_training.
        # accelerometer_check) finds these recordings' IMU right.
        y_a=x_v * r
        + 0.6 * 2 * math.pi * 0.4 * np.cos(2 * math.pi * 0.4 * t + 0.3 + seed)
        + rng.normal(0, 0.1, n),
        r=r,
        stl=0.02 * np.sin(2 * math.pi * 0.4 * t + seed),
        yaw=yaw,
    )


def quaternion(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of roll about x, then pitch about y, then yaw about z (tf2's RPY)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def write_foreign_bag(
    path: Path, truth: Truth, tilt: tuple[np.ndarray, np.ndarray] | None = None
) -> Path:
    """``tilt``: the body's roll and pitch [rad] per sample; the IMU then reads the
    accelerations in the body frame with gravity (REP 145) and its orientation carries
    the tilt and the yaw (without: level accelerations, an identity orientation)."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    Header, Time = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    Vector3, Quaternion = (
        ts.types["geometry_msgs/msg/Vector3"],
        ts.types["geometry_msgs/msg/Quaternion"],
    )
    Imu, Odometry = ts.types["sensor_msgs/msg/Imu"], ts.types["nav_msgs/msg/Odometry"]
    Float64, Vector3Stamped = (
        ts.types["std_msgs/msg/Float64"],
        ts.types["geometry_msgs/msg/Vector3Stamped"],
    )
    Pose, PoseCov = (
        ts.types["geometry_msgs/msg/Pose"],
        ts.types["geometry_msgs/msg/PoseWithCovariance"],
    )
    Twist, TwistCov = (
        ts.types["geometry_msgs/msg/Twist"],
        ts.types["geometry_msgs/msg/TwistWithCovariance"],
    )
    Point = ts.types["geometry_msgs/msg/Point"]
    cov9, cov36 = np.zeros(9), np.zeros(36)

    writer = open_writer(path, compress=False)
    conns = {
        t: writer.add_connection(t, msgtype, typestore=ts)
        for t, msgtype in (
            ("/imu/data", "sensor_msgs/msg/Imu"),
            ("/odom", "nav_msgs/msg/Odometry"),
            ("/steering_wheel_deg", "std_msgs/msg/Float64"),
            ("/ins/velocity_enu", "geometry_msgs/msg/Vector3Stamped"),
        )
    }
    for i, stamp in enumerate(truth.stamp_ns.tolist()):
        h = Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="imu_link")
        f_x, f_y, orientation = float(truth.x_a[i]), float(truth.y_a[i]), (0.0, 0.0, 0.0, 1.0)
        if tilt is not None:
            roll, pitch = float(tilt[0][i]), float(tilt[1][i])
            f_x = f_x * math.cos(pitch) - GRAVITY * math.sin(pitch)
            f_y = f_y * math.cos(roll) + GRAVITY * math.sin(roll)
            orientation = quaternion(roll, pitch, float(truth.yaw[i]))
        qx, qy, qz, qw = orientation
        imu = Imu(
            header=h,
            orientation=Quaternion(x=qx, y=qy, z=qz, w=qw),
            orientation_covariance=cov9,
            angular_velocity=Vector3(x=0.0, y=0.0, z=float(truth.r[i])),
            angular_velocity_covariance=cov9,
            linear_acceleration=Vector3(x=f_x, y=f_y, z=9.81),
            linear_acceleration_covariance=cov9,
        )
        yaw = float(truth.yaw[i])
        odom = Odometry(
            header=h,
            child_frame_id="base_link",
            pose=PoseCov(
                pose=Pose(
                    position=Point(x=0.0, y=0.0, z=0.0),
                    orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
                ),
                covariance=cov36,
            ),
            twist=TwistCov(
                twist=Twist(
                    linear=Vector3(x=float(truth.x_v[i]), y=float(truth.y_v[i]), z=0.0),
                    angular=Vector3(x=0.0, y=0.0, z=float(truth.r[i])),
                ),
                covariance=cov36,
            ),
        )
        c, s = math.cos(yaw), math.sin(yaw)
        east = c * truth.x_v[i] - s * truth.y_v[i]
        north = s * truth.x_v[i] + c * truth.y_v[i]
        vel = Vector3Stamped(header=h, vector=Vector3(x=float(east), y=float(north), z=0.0))
        wheel = Float64(data=float(truth.stl[i] / RACK_PER_WHEEL_DEG))
        for topic, msg in (
            ("/imu/data", imu),
            ("/odom", odom),
            ("/steering_wheel_deg", wheel),
            ("/ins/velocity_enu", vel),
        ):
            conn = conns[topic]
            writer.write(conn, stamp, ts.serialize_cdr(msg, conn.msgtype))
    writer.close()
    return path
