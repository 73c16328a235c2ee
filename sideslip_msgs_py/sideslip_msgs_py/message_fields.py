"""What the contract reads from a message: the per-topic field records and their readers.

A record per sensor topic (:data:`ImuFields`, :data:`TwistFields`,
:data:`SteeringFields`: ``stamp_ns`` then the topic's channels in registry order) is what
the estimator core takes, one message at a time; the readers take each channel at its
registry field path (:mod:`.channels`), from rclpy messages and rosbags dataclasses
alike. Re-exported by :mod:`.messages`, which builds the messages.
"""

from __future__ import annotations

from typing import Any, Final, NamedTuple

from . import channels as registry
from . import topics
from .errors import MessageFieldError
from .field_path import FieldPathError, getter
from .sample import GroundTruth

NS_PER_S: Final = 1_000_000_000


def _fields_record(topic: str, name: str) -> Any:
    """A NamedTuple ``name(stamp_ns, <the topic's channels in registry order>)``."""
    record = NamedTuple(  # type: ignore[misc]  # fields from the registry
        name, [("stamp_ns", int), *((ch.name, float) for ch in registry.on_topic(topic))]
    )
    record.__doc__ = f"What the contract reads from {topic}: stamp [ns] and " + ", ".join(
        f"{ch.name} [{ch.unit}]" for ch in registry.on_topic(topic)
    )
    record.__module__ = __name__
    return record


ImuFields = _fields_record(topics.IMU, "ImuFields")
TwistFields = _fields_record(topics.TWIST, "TwistFields")
SteeringFields = _fields_record(topics.STEERING, "SteeringFields")
FIELDS_RECORDS: Final[dict[str, Any]] = {
    topics.IMU: ImuFields,
    topics.TWIST: TwistFields,
    topics.STEERING: SteeringFields,
}
"""Per sensor topic, the record of what the contract reads from it (rate NaN when the
steering does not publish one)."""


class GroundTruthFields(NamedTuple):
    """What the contract reads from /vehicle/ground_truth/twist."""

    stamp_ns: int
    truth: GroundTruth


def stamp_ns(msg: Any) -> int:
    """``msg.header.stamp`` as integer nanoseconds."""
    stamp = msg.header.stamp
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def _readers(topic: str) -> tuple[tuple[registry.Channel, Any], ...]:
    return tuple((ch, getter(ch.field)) for ch in registry.on_topic(topic))


_READERS: Final = {t: _readers(t) for t in (*topics.SENSOR_TOPICS, topics.GROUND_TRUTH_TWIST)}


def channel_values(msg: Any, topic: str, name: str | None = None) -> list[float]:
    """The values of ``topic``'s registry channels in ``msg`` (either back-end), in order.

    ``name`` is the topic as subscribed, for errors (default ``topic``). Raises
    :class:`MessageFieldError` naming it when a required field is missing; an optional
    one (the steering rate) is NaN then.
    """
    values = []
    for ch, get in _READERS[topic]:
        try:
            values.append(float(get(msg)))
        except (AttributeError, FieldPathError, IndexError) as err:
            if ch.required:
                raise MessageFieldError(f"{name or topic}: {err}") from None
            values.append(float("nan"))
    return values


def imu_fields(msg: Any) -> Any:
    """X_a, Y_a [m/s²] and ψ̇ [rad/s] (:data:`ImuFields`) of an Imu message of either back-end."""
    return ImuFields(stamp_ns(msg), *channel_values(msg, topics.IMU))


def twist_fields(msg: Any) -> Any:
    """X_v, Y_v [m/s] (:data:`TwistFields`) of a TwistStamped message of either back-end."""
    return TwistFields(stamp_ns(msg), *channel_values(msg, topics.TWIST))


def steering_fields(msg: Any, topic: str = topics.STEERING) -> Any:
    """STL [m] and its rate [m/s] (:data:`SteeringFields`) of the ``steering_rack`` joint.

    Raises :class:`MessageFieldError` when the joint or its position is missing. A
    missing velocity gives NaN: real steering sensors often publish position only.
    """
    return SteeringFields(stamp_ns(msg), *channel_values(msg, topics.STEERING, topic))


def ground_truth_fields(msg: Any) -> GroundTruthFields:
    """Exact v_x, v_y [m/s] and ψ̇ [rad/s] of a ground-truth TwistStamped."""
    values = channel_values(msg, topics.GROUND_TRUTH_TWIST)
    names = [ch.name.removeprefix(registry.TRUTH_PREFIX) for ch in registry.TRUTH]
    return GroundTruthFields(stamp_ns(msg), GroundTruth(**dict(zip(names, values, strict=True))))
