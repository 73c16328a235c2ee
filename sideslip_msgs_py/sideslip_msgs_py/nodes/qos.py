"""rclpy ``QoSProfile`` objects from the contract's :class:`~sideslip_msgs_py.qos.QosSpec`."""

from __future__ import annotations

from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from ..qos import QosSpec, qos_for


def to_rclpy(spec: QosSpec) -> QoSProfile:
    """The rclpy profile with exactly the policies of ``spec``."""

    def duration(ns: int) -> Duration:
        return Duration(nanoseconds=ns)

    return QoSProfile(
        history=HistoryPolicy[spec.history.name],
        depth=spec.depth,
        reliability=ReliabilityPolicy[spec.reliability.name],
        durability=DurabilityPolicy[spec.durability.name],
        deadline=duration(spec.deadline_ns),
        lifespan=duration(spec.lifespan_ns),
        liveliness=LivelinessPolicy[spec.liveliness.name],
        liveliness_lease_duration=duration(spec.liveliness_lease_duration_ns),
        avoid_ros_namespace_conventions=spec.avoid_ros_namespace_conventions,
    )


def profile_for(topic: str) -> QoSProfile:
    """The rclpy QoS of a contract topic (raises UnknownTopicError for other names)."""
    return to_rclpy(qos_for(topic))
