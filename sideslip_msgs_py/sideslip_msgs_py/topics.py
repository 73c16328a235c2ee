"""Topic names, ROS type names and frame/joint names of the wire contract.

This module is the only place in the project that spells a topic name. Every topic
uses a standard interface (no custom .msg), so any ROS 2 stack can subscribe without
building our packages. Which field carries which channel, in which unit, is the
registry's (:mod:`sideslip_msgs_py.channels`); :mod:`sideslip_msgs_py.messages` builds
and reads the messages.
"""

from __future__ import annotations

from typing import Final

# --- Topics -----------------------------------------------------------------------------
IMU: Final = "/vehicle/imu"
"""sensor_msgs/Imu: linear_acceleration.x/.y = X_a, Y_a [m/s²]; angular_velocity.z = ψ̇ [rad/s]."""

TWIST: Final = "/vehicle/twist"
"""geometry_msgs/TwistStamped: linear.x/.y = X_v, Y_v [m/s], body frame at the CG."""

STEERING: Final = "/vehicle/steering"
"""sensor_msgs/JointState: joint ``steering_rack``, position = STL [m], velocity [m/s]."""

GROUND_TRUTH_TWIST: Final = "/vehicle/ground_truth/twist"
"""geometry_msgs/TwistStamped: exact body velocity at the CG and exact yaw rate."""

GROUND_TRUTH_SIDESLIP: Final = "/vehicle/ground_truth/sideslip"
"""std_msgs/Float64: exact β = atan2(v_y, v_x) [rad]."""

SIDESLIP: Final = "/sideslip"
"""std_msgs/Float64: estimated β [rad] (estimator output)."""

SIDESLIP_TWIST: Final = "/sideslip/twist"
"""geometry_msgs/TwistWithCovarianceStamped: v_x and v_y = v_x·tan β̂ with covariance."""

SIDESLIP_STATUS: Final = "/sideslip/status"
"""diagnostic_msgs/DiagnosticArray: estimator health (OK/WARN/ERROR and key values)."""

CLOCK: Final = "/clock"
"""rosgraph_msgs/Clock: simulated time when running faster than real time."""

# --- ROS 2 type names (the 'pkg/msg/Name' form used by rosbag2 and rosbags) ------------
IMU_TYPE: Final = "sensor_msgs/msg/Imu"
TWIST_STAMPED_TYPE: Final = "geometry_msgs/msg/TwistStamped"
JOINT_STATE_TYPE: Final = "sensor_msgs/msg/JointState"
FLOAT64_TYPE: Final = "std_msgs/msg/Float64"
TWIST_WITH_COVARIANCE_STAMPED_TYPE: Final = "geometry_msgs/msg/TwistWithCovarianceStamped"
DIAGNOSTIC_ARRAY_TYPE: Final = "diagnostic_msgs/msg/DiagnosticArray"
CLOCK_TYPE: Final = "rosgraph_msgs/msg/Clock"

TOPIC_TYPES: Final[dict[str, str]] = {
    IMU: IMU_TYPE,
    TWIST: TWIST_STAMPED_TYPE,
    STEERING: JOINT_STATE_TYPE,
    GROUND_TRUTH_TWIST: TWIST_STAMPED_TYPE,
    GROUND_TRUTH_SIDESLIP: FLOAT64_TYPE,
    SIDESLIP: FLOAT64_TYPE,
    SIDESLIP_TWIST: TWIST_WITH_COVARIANCE_STAMPED_TYPE,
    SIDESLIP_STATUS: DIAGNOSTIC_ARRAY_TYPE,
    CLOCK: CLOCK_TYPE,
}
"""Every contract topic and its ROS 2 type name."""

# --- Frames and joints -------------------------------------------------------------------
BASE_FRAME: Final = "base_link"
"""Frame id of every stamped vehicle message: body frame at the CG (REP-103, x fwd, y left)."""

STEERING_JOINT: Final = "steering_rack"
"""JointState name of the steering rack; position is the rack travel STL [m]."""

# --- Groups --------------------------------------------------------------------------------
SENSOR_TOPICS: Final[tuple[str, ...]] = (TWIST, STEERING, IMU)
"""What the vehicle's sensors publish; every sample needs all three.

In publish order, the IMU last: the estimator forms a sample when an IMU message
arrives, from the latest twist and steering, so a step whose messages share one stamp
should send its twist and steering first (the sim node and our bags do). DDS does not
order messages across topics, so this is a preference, not a guarantee: a twist that
arrives after its IMU leaves that sample with the previous step's twist (2.5 ms older,
within max_input_age_s)."""

GROUND_TRUTH_TOPICS: Final[tuple[str, ...]] = (GROUND_TRUTH_TWIST, GROUND_TRUTH_SIDESLIP)
"""Simulator-only labels; optional in bags recorded from a real car."""

ESTIMATOR_TOPICS: Final[tuple[str, ...]] = (SIDESLIP, SIDESLIP_TWIST, SIDESLIP_STATUS)
"""What the estimator publishes."""

SAMPLE_TOPICS: Final[tuple[str, ...]] = SENSOR_TOPICS + GROUND_TRUTH_TOPICS
"""Topics that one simulator step publishes (and one bag sample holds), in write order."""
