"""QoS of recorded and replayed topics: what publishers offer and what we ask for.

A publisher's QoS reaches us in three forms: an rclpy ``QoSProfile`` from the ROS
graph (``get_publishers_info_by_topic``), a ``rosbags.interfaces.Qos`` read from a
bag's metadata, or a rosbag2 YAML entry (an MCAP channel's ``offered_qos_profiles``).
:class:`OfferedQos` holds any of them verbatim, including the ``unknown`` history and
depth 0 that DDS discovery reports, so that a recorded bag says exactly what was
offered, as ``ros2 bag record`` does.

The adaptation rules follow rosbag2:

* recording (:func:`subscription_qos`): reliable only when every publisher offers
  reliable, transient-local only when every publisher does; otherwise best effort /
  volatile, which matches any publisher. The history is deep so that DDS holds
  messages while Python catches up.
* replaying (:func:`publisher_qos`): offer what the recorded publishers offered; where
  they disagree, the most permissive choice (best effort, volatile).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final

from sideslip_msgs_py.qos import (
    Durability,
    History,
    Liveliness,
    QosSpec,
    Reliability,
    rosbags_qos,
)

if TYPE_CHECKING:
    from rosbags.interfaces import Qos

RECORD_DEPTH: Final = 10_000
"""Keep-last depth of the recorder's subscriptions: messages per topic that DDS holds
while the recorder is busy (25 s of a 400 Hz topic)."""

RELIABLE_PLAY_DEPTH: Final = 10_000
"""Keep-last depth of every publisher under ``sideslip-play --reliable``: messages per
topic kept until each subscriber has acknowledged them."""

DEFAULT_DEPTH: Final = 10
"""Depth used when the offers do not say (DDS discovery reports depth 0), as rosbag2."""

INFINITE_NS: Final = 2**63 - 1
"""rmw's "infinite" duration in ns; rosbag2 writes it as sec 9223372036, nsec 854775807."""

_NS_PER_S: Final = 1_000_000_000
_LARGEST_FINITE_S: Final = 2**31 - 1  # older rosbag2 wrote "infinite" as 2147483647 s

# rosbag2 metadata v8 stores the rmw enum values; v9 stores these names.
_HISTORY: Final = ("system_default", "keep_last", "keep_all", "unknown")
_RELIABILITY: Final = ("system_default", "reliable", "best_effort", "unknown", "best_available")
_DURABILITY: Final = ("system_default", "transient_local", "volatile", "unknown", "best_available")
_LIVELINESS: Final = (
    "system_default",
    "automatic",
    "manual_by_node",
    "manual_by_topic",
    "unknown",
    "best_available",
)


@dataclass(frozen=True, slots=True)
class OfferedQos:
    """One QoS profile as a publisher offered it (a :class:`~sideslip_msgs_py.qos.QosProfile`).

    Policies are rosbag2 v9 names (``"reliable"``, ``"keep_last"``, ``"unknown"``, ...).
    Durations are in nanoseconds as offered: 0 is "unspecified", :data:`INFINITE_NS`
    is rmw's "infinite".
    """

    history: str = "unknown"
    depth: int = 0
    reliability: str = "unknown"
    durability: str = "unknown"
    deadline_ns: int = 0
    lifespan_ns: int = 0
    liveliness: str = "unknown"
    liveliness_lease_duration_ns: int = 0
    avoid_ros_namespace_conventions: bool = False

    @classmethod
    def from_rclpy(cls, profile: Any) -> OfferedQos:
        """From an rclpy ``QoSProfile`` (policies are enums, durations ``Duration``)."""
        return cls(
            history=profile.history.name.lower(),
            depth=int(profile.depth),
            reliability=profile.reliability.name.lower(),
            durability=profile.durability.name.lower(),
            deadline_ns=int(profile.deadline.nanoseconds),
            lifespan_ns=int(profile.lifespan.nanoseconds),
            liveliness=profile.liveliness.name.lower(),
            liveliness_lease_duration_ns=int(profile.liveliness_lease_duration.nanoseconds),
            avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions),
        )

    @classmethod
    def from_rosbags(cls, qos: Qos) -> OfferedQos:
        """From a ``rosbags.interfaces.Qos`` (what rosbags' Reader gives per connection)."""
        return cls(
            history=qos.history.name.lower(),
            depth=int(qos.depth),
            reliability=qos.reliability.name.lower(),
            durability=qos.durability.name.lower(),
            deadline_ns=qos.deadline.sec * _NS_PER_S + qos.deadline.nsec,
            lifespan_ns=qos.lifespan.sec * _NS_PER_S + qos.lifespan.nsec,
            liveliness=qos.liveliness.name.lower(),
            liveliness_lease_duration_ns=qos.liveliness_lease_duration.sec * _NS_PER_S
            + qos.liveliness_lease_duration.nsec,
            avoid_ros_namespace_conventions=bool(qos.avoid_ros_namespace_conventions),
        )

    @classmethod
    def from_rosbag2_dict(cls, entry: Mapping[str, Any]) -> OfferedQos:
        """From one rosbag2 ``offered_qos_profiles`` entry (v9 names or v8 integers).

        Raises:
            ValueError: a policy value that is neither a known name nor index.
        """
        return cls(
            history=_policy(entry.get("history", "unknown"), _HISTORY, "history"),
            depth=int(entry.get("depth", 0)),
            reliability=_policy(entry.get("reliability", "unknown"), _RELIABILITY, "reliability"),
            durability=_policy(entry.get("durability", "unknown"), _DURABILITY, "durability"),
            deadline_ns=_duration_ns(entry.get("deadline")),
            lifespan_ns=_duration_ns(entry.get("lifespan")),
            liveliness=_policy(entry.get("liveliness", "unknown"), _LIVELINESS, "liveliness"),
            liveliness_lease_duration_ns=_duration_ns(entry.get("liveliness_lease_duration")),
            avoid_ros_namespace_conventions=bool(
                entry.get("avoid_ros_namespace_conventions", False)
            ),
        )

    def to_rosbags(self) -> Qos:
        """As a ``rosbags.interfaces.Qos`` (what rosbags' Writer records)."""
        return rosbags_qos(self)


def _policy(value: Any, names: Sequence[str], what: str) -> str:
    if isinstance(value, bool):  # bool is an int: refuse it rather than read True as 1
        msg = f"QoS {what}: {value!r} is not a policy"
        raise ValueError(msg)
    if isinstance(value, int) and 0 <= value < len(names):
        return names[value]
    if isinstance(value, str) and value.lower() in names:
        return value.lower()
    msg = f"QoS {what}: {value!r} is not one of {', '.join(names)}"
    raise ValueError(msg)


def _duration_ns(value: Any) -> int:
    if not isinstance(value, Mapping):
        return 0
    return int(value.get("sec", 0)) * _NS_PER_S + int(value.get("nsec", 0))


def parse_offered_qos_yaml(text: str) -> list[OfferedQos]:
    """Profiles from rosbag2's ``offered_qos_profiles`` YAML text (MCAP channel metadata).

    Raises:
        ValueError: not YAML, not a list of mappings, or a bad policy value.
    """
    import yaml

    try:
        doc = yaml.safe_load(text) if text.strip() else []
    except yaml.YAMLError as err:
        msg = f"offered_qos_profiles is not YAML: {err}"
        raise ValueError(msg) from None
    if not isinstance(doc, list) or not all(isinstance(e, Mapping) for e in doc):
        msg = f"offered_qos_profiles is not a list of profiles: {text[:80]!r}"
        raise ValueError(msg)
    return [OfferedQos.from_rosbag2_dict(e) for e in doc]


# --- adaptation ----------------------------------------------------------------------------


def all_reliable(offers: Sequence[OfferedQos]) -> bool:
    """True when there are offers and every one is reliable."""
    return bool(offers) and all(o.reliability == "reliable" for o in offers)


def subscription_qos(offers: Sequence[OfferedQos]) -> QosSpec:
    """The recorder's subscription QoS for a topic with these publishers (rosbag2 rule).

    Reliable only when every offer is reliable (a reliable subscription does not match a
    best-effort publisher); transient-local only when every offer is. Keep last
    :data:`RECORD_DEPTH`.
    """
    reliable = all_reliable(offers)
    transient = bool(offers) and all(o.durability == "transient_local" for o in offers)
    return QosSpec(
        Reliability.RELIABLE if reliable else Reliability.BEST_EFFORT,
        Durability.TRANSIENT_LOCAL if transient else Durability.VOLATILE,
        History.KEEP_LAST,
        RECORD_DEPTH,
    )


def publisher_qos(offers: Sequence[OfferedQos]) -> QosSpec | None:
    """The QoS to replay a topic with, from its recorded offers; None when there are none.

    Policies all offers agree on are kept; otherwise best effort, volatile and default
    liveliness, which every subscriber accepts. The depth is the largest keep-last depth
    offered, or :data:`DEFAULT_DEPTH` when discovery did not report one. Durations are
    kept when all offers give the same finite value, else left unspecified (0).
    """
    if not offers:
        return None
    if all(o.history == "keep_all" for o in offers):
        history, depth = History.KEEP_ALL, DEFAULT_DEPTH
    else:
        depths = [o.depth for o in offers if o.history != "keep_all" and o.depth > 0]
        history, depth = History.KEEP_LAST, max(depths, default=DEFAULT_DEPTH)
    return QosSpec(
        reliability=_agreed(offers, "reliability", Reliability, Reliability.BEST_EFFORT),
        durability=_agreed(offers, "durability", Durability, Durability.VOLATILE),
        history=history,
        depth=depth,
        deadline_ns=_agreed_duration(offers, "deadline_ns"),
        lifespan_ns=_agreed_duration(offers, "lifespan_ns"),
        liveliness=_agreed(offers, "liveliness", Liveliness, Liveliness.SYSTEM_DEFAULT),
        liveliness_lease_duration_ns=_agreed_duration(offers, "liveliness_lease_duration_ns"),
        avoid_ros_namespace_conventions=all(o.avoid_ros_namespace_conventions for o in offers),
    )


def _agreed(offers: Sequence[OfferedQos], attr: str, enum: Any, fallback: Any) -> Any:
    values = {getattr(o, attr) for o in offers}
    if len(values) == 1:
        (value,) = values
        if value in {e.value for e in enum}:
            return enum(value)
    return fallback


def _agreed_duration(offers: Sequence[OfferedQos], attr: str) -> int:
    values = {getattr(o, attr) for o in offers}
    if len(values) != 1:
        return 0
    (ns,) = values
    return ns if 0 < ns < _LARGEST_FINITE_S * _NS_PER_S else 0  # infinite == unspecified


def reliable(spec: QosSpec) -> QosSpec:
    """``spec`` made reliable with a keep-last :data:`RELIABLE_PLAY_DEPTH` history."""
    return dataclasses.replace(
        spec,
        reliability=Reliability.RELIABLE,
        history=History.KEEP_LAST,
        depth=RELIABLE_PLAY_DEPTH,
    )


def describe(spec: QosSpec) -> str:
    """Short human form, e.g. ``reliable/volatile/keep_last 10``."""
    depth = f" {spec.depth}" if spec.history == History.KEEP_LAST else ""
    return f"{spec.reliability}/{spec.durability}/{spec.history}{depth}"
