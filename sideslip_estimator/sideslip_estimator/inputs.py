"""Input checks and alignment of the three sensor streams on the IMU stamp.

Each sensor topic arrives on its own; a model sample is formed when an IMU message
arrives, from its accelerations and yaw rate plus the twist and steering of its time:
the latest at or before the IMU stamp among the last few received (as the bag reader
aligns them, so a model sees in the node what it saw in training), else the oldest
held (a clock slightly ahead). DDS does not order messages of different topics: when
the IMU lags behind the twist on a loaded machine, the twist of the IMU's own step is
still found. A sample is rejected (never passed on) when one of those inputs is
missing, further than ``max_input_age_s`` from the IMU stamp, or a message held a
non-finite or physically absurd value.

Which field of which topic gives which window column, and the bound each model input is
checked against, come from the contract's registry (``sideslip_msgs_py.channels``).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Final

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py import channels as registry
from sideslip_msgs_py import topics
from sideslip_msgs_py.features import CHANNELS, channel_indices
from sideslip_msgs_py.messages import NS_PER_S, ImuFields, SteeringFields, TwistFields

HISTORY: Final = 16
"""Twist and steering messages kept for alignment (40 ms at 400 Hz)."""

X_V, Y_V, X_A, Y_A, YAW_RATE, STL = channel_indices(
    ("x_v_mps", "y_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m")
)


@dataclass(frozen=True)
class InputLimits:
    """Largest magnitude accepted per quantity; anything beyond is a sensor fault.

    Defaults are far outside what a road car reaches (about 5 g, 360 km/h, 290 deg/s),
    so they catch faults without clipping real data. STL is the paper's steering-bar
    travel, whose scale is the vehicle's: our simulated cars reach 0.98 m (paper_sedan)
    to 1.33 m (the fleet's slowest steering) at full lock, hence 1.5 m.
    """

    speed_mps: float = 100.0
    acceleration_mps2: float = 50.0
    yaw_rate_radps: float = 5.0
    stl_m: float = 1.5

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (math.isfinite(value) and value > 0.0):
                msg = f"InputLimits.{name} must be finite and > 0, got {value!r}"
                raise ValueError(msg)


class InputRejected(ValueError):
    """A message or sample that must not reach the model; ``reason`` is a short key."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(detail)
        self.reason = reason


def _check(topic: str, field: str, value: float, limit: float) -> None:
    if not math.isfinite(value):
        raise InputRejected("non_finite", f"{topic}: {field} is {value}")
    if abs(value) > limit:
        raise InputRejected("out_of_range", f"{topic}: {field} = {value:g} beyond ±{limit:g}")


_CHECKED: Final[dict[str, tuple[registry.Channel, ...]]] = {
    topic: tuple(ch for ch in registry.on_topic(topic) if ch.limit is not None)
    for topic in topics.SENSOR_TOPICS
}
"""Per sensor topic, the channels checked against a bound (the rack's rate is not: it is
no model input, and a missing (NaN) rate is normal for real sensors)."""


def check_fields(contract_topic: str, topic: str, f: tuple, limits: InputLimits) -> None:
    """Raise :class:`InputRejected` naming ``topic`` and the field when a value of a
    ``contract_topic`` record (``ImuFields``, ...) is non-finite or beyond its bound."""
    for ch in _CHECKED[contract_topic]:
        _check(topic, ch.field, getattr(f, ch.name), getattr(limits, ch.limit))


def check_imu(topic: str, f: ImuFields, limits: InputLimits) -> None:
    """Raise :class:`InputRejected` naming the field when an IMU value is unusable."""
    check_fields(topics.IMU, topic, f, limits)


def check_twist(topic: str, f: TwistFields, limits: InputLimits) -> None:
    check_fields(topics.TWIST, topic, f, limits)


def check_steering(topic: str, f: SteeringFields, limits: InputLimits) -> None:
    check_fields(topics.STEERING, topic, f, limits)


def _window_columns(topic: str) -> tuple[tuple[int, int], ...]:
    """(index in ``topic``'s fields record, window column) of each model input it gives."""
    names = [ch.name for ch in registry.on_topic(topic)]
    return tuple((names.index(n) + 1, CHANNELS.index(n)) for n in names if n in CHANNELS)


_COLUMNS: Final = {topic: _window_columns(topic) for topic in topics.SENSOR_TOPICS}


class Aligner:
    """Holds the latest twist and steering and forms a sample on each IMU message."""

    def __init__(self, max_input_age_s: float) -> None:
        if not (math.isfinite(max_input_age_s) and max_input_age_s > 0.0):
            msg = f"max_input_age_s must be finite and > 0, got {max_input_age_s!r}"
            raise ValueError(msg)
        self.max_age_ns = round(max_input_age_s * NS_PER_S)
        self._twists: deque[TwistFields] = deque(maxlen=HISTORY)
        self._steerings: deque[SteeringFields] = deque(maxlen=HISTORY)
        self._row = np.zeros(len(CHANNELS))

    def add_twist(self, fields: TwistFields) -> None:
        self._twists.append(fields)

    def add_steering(self, fields: SteeringFields) -> None:
        self._steerings.append(fields)

    @property
    def twist(self) -> TwistFields | None:
        """The latest twist received (None before the first)."""
        return self._twists[-1] if self._twists else None

    @twist.setter
    def twist(self, fields: TwistFields) -> None:
        self.add_twist(fields)

    @property
    def steering(self) -> SteeringFields | None:
        """The latest steering received (None before the first)."""
        return self._steerings[-1] if self._steerings else None

    @steering.setter
    def steering(self, fields: SteeringFields) -> None:
        self.add_steering(fields)

    def forget_after(self, imu_stamp_ns: int) -> None:
        """Drop held inputs stamped later than ``imu_stamp_ns`` + the age limit: after a
        stamp jump backwards they belong to the old time line."""
        limit = imu_stamp_ns + self.max_age_ns
        for held in (self._twists, self._steerings):
            kept = [f for f in held if f.stamp_ns <= limit]
            held.clear()
            held.extend(kept)

    @staticmethod
    def _of_time(held: deque, imu_stamp_ns: int):  # type: ignore[no-untyped-def]
        """The held message with the latest stamp at or before the IMU stamp (of equal
        stamps the last received), else the one with the earliest stamp."""
        best = None
        for fields in reversed(held):
            if fields.stamp_ns <= imu_stamp_ns and (
                best is None or fields.stamp_ns > best.stamp_ns
            ):
                best = fields
        if best is None and held:
            best = min(held, key=lambda f: f.stamp_ns)
        return best

    def _age_ok(self, name: str, imu_stamp_ns: int, stamp_ns: int) -> None:
        age = imu_stamp_ns - stamp_ns
        # Also refuse inputs far *ahead* of the IMU: two clocks that disagree.
        if abs(age) > self.max_age_ns:
            raise InputRejected(
                f"stale_{name}",
                f"{name} stamp is {age / 1e6:+.1f} ms from the IMU stamp "
                f"(limit ±{self.max_age_ns / 1e6:.1f} ms)",
            )

    def sample(self, imu: ImuFields) -> npt.NDArray[np.float64]:
        """The model row for this IMU message (a buffer reused by the next call)."""
        twist = self._of_time(self._twists, imu.stamp_ns)
        steering = self._of_time(self._steerings, imu.stamp_ns)
        if twist is None:
            raise InputRejected("no_twist", "no twist received yet")
        if steering is None:
            raise InputRejected("no_steering", "no steering received yet")
        self._age_ok("twist", imu.stamp_ns, twist.stamp_ns)
        self._age_ok("steering", imu.stamp_ns, steering.stamp_ns)
        row = self._row
        for topic, fields in (
            (topics.TWIST, twist),
            (topics.STEERING, steering),
            (topics.IMU, imu),
        ):
            for i, column in _COLUMNS[topic]:
                row[column] = fields[i]
        return row
