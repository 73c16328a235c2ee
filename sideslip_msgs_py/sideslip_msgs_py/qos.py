"""Quality of service of every contract topic, as plain data.

Nodes turn a :class:`QosSpec` into an ``rclpy.qos.QoSProfile`` (the enum values are the
lower-case names rclpy and rosbag2 use), and the bag writer records it as the topic's
``offered_qos_profiles`` so that ``ros2 bag play`` offers the same QoS again.
:func:`rosbags_qos` is the one conversion to rosbags' form of an offered profile, for a
:class:`QosSpec` and for any other :class:`QosProfile` (the recorder's offered QoS).

Choice of profiles: the 400 Hz sensor streams and the ground truth use the sensor-data
profile (best effort, keep last 5, like rclpy's ``qos_profile_sensor_data``): a late sample
is worthless and must not block the publisher. The estimator's outputs are reliable so
that a controller or a recorder sees every estimate.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum
from types import MappingProxyType
from typing import TYPE_CHECKING, Final, Protocol

from . import topics
from .errors import UnknownTopicError

if TYPE_CHECKING:
    from rosbags.interfaces import Qos


class Reliability(StrEnum):
    """QoS reliability policy (rosbag2/rclpy names)."""

    SYSTEM_DEFAULT = "system_default"
    RELIABLE = "reliable"
    BEST_EFFORT = "best_effort"


class Durability(StrEnum):
    """QoS durability policy."""

    SYSTEM_DEFAULT = "system_default"
    TRANSIENT_LOCAL = "transient_local"
    VOLATILE = "volatile"


class History(StrEnum):
    """QoS history policy."""

    SYSTEM_DEFAULT = "system_default"
    KEEP_LAST = "keep_last"
    KEEP_ALL = "keep_all"


class Liveliness(StrEnum):
    """QoS liveliness policy."""

    SYSTEM_DEFAULT = "system_default"
    AUTOMATIC = "automatic"
    MANUAL_BY_TOPIC = "manual_by_topic"


@dataclass(frozen=True, slots=True)
class QosSpec:
    """One QoS profile.

    Durations are in nanoseconds; 0 means "unspecified" (the RMW default, which for
    deadline, lifespan and lease duration is "infinite"), exactly like ``Duration()`` in
    an rclpy ``QoSProfile``.
    """

    reliability: Reliability
    durability: Durability
    history: History
    depth: int
    deadline_ns: int = 0
    lifespan_ns: int = 0
    liveliness: Liveliness = Liveliness.SYSTEM_DEFAULT
    liveliness_lease_duration_ns: int = 0
    avoid_ros_namespace_conventions: bool = False

    def to_rosbag2_dict(self) -> dict[str, object]:
        """The profile as one entry of rosbag2's ``offered_qos_profiles`` (metadata v9)."""
        return {
            "history": self.history.value,
            "depth": self.depth,
            "reliability": self.reliability.value,
            "durability": self.durability.value,
            "deadline": _sec_nsec(self.deadline_ns),
            "lifespan": _sec_nsec(self.lifespan_ns),
            "liveliness": self.liveliness.value,
            "liveliness_lease_duration": _sec_nsec(self.liveliness_lease_duration_ns),
            "avoid_ros_namespace_conventions": self.avoid_ros_namespace_conventions,
        }

    def to_rosbags(self) -> Qos:
        """The profile as a ``rosbags.interfaces.Qos`` (what rosbags' Writer takes)."""
        return rosbags_qos(self)


class QosProfile(Protocol):
    """Any description of one QoS profile: rosbag2 v9 policy names and durations in ns.

    Policies are lower-case names (``"reliable"``, ``"keep_last"``, and also
    ``"unknown"`` or ``"best_available"`` where a publisher offered them); durations are
    nanoseconds, 0 meaning "unspecified". :class:`QosSpec` is one.
    """

    @property
    def history(self) -> str: ...
    @property
    def depth(self) -> int: ...
    @property
    def reliability(self) -> str: ...
    @property
    def durability(self) -> str: ...
    @property
    def deadline_ns(self) -> int: ...
    @property
    def lifespan_ns(self) -> int: ...
    @property
    def liveliness(self) -> str: ...
    @property
    def liveliness_lease_duration_ns(self) -> int: ...
    @property
    def avoid_ros_namespace_conventions(self) -> bool: ...


def rosbags_qos(profile: QosProfile) -> Qos:
    """``profile`` as a ``rosbags.interfaces.Qos``: one entry of a connection's offered QoS
    profiles, what rosbags' Writer records and its Reader gives back.

    Raises:
        KeyError: a policy name that rosbags does not know.
    """
    from rosbags.interfaces import (  # lazy: rosbags is only needed for bags
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    def qtime(ns: int) -> QosTime:
        return QosTime(**_sec_nsec(ns))

    return Qos(
        history=QosHistory[profile.history.upper()],
        depth=profile.depth,
        reliability=QosReliability[profile.reliability.upper()],
        durability=QosDurability[profile.durability.upper()],
        deadline=qtime(profile.deadline_ns),
        lifespan=qtime(profile.lifespan_ns),
        liveliness=QosLiveliness[profile.liveliness.upper()],
        liveliness_lease_duration=qtime(profile.liveliness_lease_duration_ns),
        avoid_ros_namespace_conventions=profile.avoid_ros_namespace_conventions,
    )


def _sec_nsec(ns: int) -> dict[str, int]:
    sec, nsec = divmod(ns, 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


SENSOR_DATA: Final = QosSpec(Reliability.BEST_EFFORT, Durability.VOLATILE, History.KEEP_LAST, 5)
"""Best effort, volatile, keep last 5: rclpy's ``qos_profile_sensor_data``."""

RELIABLE: Final = QosSpec(Reliability.RELIABLE, Durability.VOLATILE, History.KEEP_LAST, 10)
"""Reliable, volatile, keep last 10: rclpy's default publisher profile."""

CLOCK: Final = QosSpec(Reliability.BEST_EFFORT, Durability.VOLATILE, History.KEEP_LAST, 1)
"""What rclpy's time source subscribes ``/clock`` with (best effort, keep last 1)."""

TOPIC_QOS: Final[Mapping[str, QosSpec]] = MappingProxyType(
    {
        topics.IMU: SENSOR_DATA,
        topics.TWIST: SENSOR_DATA,
        topics.STEERING: SENSOR_DATA,
        topics.GROUND_TRUTH_TWIST: SENSOR_DATA,
        topics.GROUND_TRUTH_SIDESLIP: SENSOR_DATA,
        topics.SIDESLIP: RELIABLE,
        topics.SIDESLIP_TWIST: RELIABLE,
        topics.SIDESLIP_STATUS: RELIABLE,
        topics.CLOCK: CLOCK,
    }
)
"""The QoS of every contract topic."""


def qos_for(topic: str) -> QosSpec:
    """QoS of a contract topic; raises :class:`UnknownTopicError` for any other name."""
    try:
        return TOPIC_QOS[topic]
    except KeyError:
        known = ", ".join(sorted(TOPIC_QOS))
        msg = f"topic {topic!r} is not in the sideslip wire contract (known: {known})"
        raise UnknownTopicError(msg) from None


def offered_qos_profiles_yaml(topic: str) -> str:
    """rosbag2 (Jazzy) ``offered_qos_profiles`` YAML string for a contract topic.

    This is the string that rosbag2 stores in an MCAP channel's metadata: a YAML list
    with one profile. (In metadata.yaml v9 the same list is stored as YAML structure.)
    """
    entry = qos_for(topic).to_rosbag2_dict()
    lines = []
    for i, (key, value) in enumerate(entry.items()):
        prefix = "- " if i == 0 else "  "
        if isinstance(value, dict):
            lines.append(f"{prefix}{key}:")
            lines.extend(f"    {k}: {v}" for k, v in value.items())
        elif isinstance(value, bool):
            lines.append(f"{prefix}{key}: {str(value).lower()}")
        else:
            lines.append(f"{prefix}{key}: {value}")
    return "\n".join(lines)
