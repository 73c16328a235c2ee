"""The channel registry: every value the contract carries, said once.

One :class:`Channel` per value: its name (the :class:`~.sample.VehicleSample` attribute
and :class:`~.sample.SampleArrays` column), unit and meaning, the contract topic and the
field of that topic's standard message that carries it, its noise σ and plausibility
bound, and which model feature sets read it. Everything else derives from here:

* :mod:`.sample`: the sample records' channel fields, ``SENSOR_CHANNELS``,
  ``TRUTH_CHANNELS`` and :class:`~.sample.SensorNoiseSigma`'s fields (from :data:`NOISE`);
* :mod:`.features`: ``CHANNELS`` (the model inputs) and the feature sets;
* :mod:`.messages` and :mod:`.message_fields`: building and reading the messages, the
  per-topic field records (``ImuFields``, ...) and the IMU covariances;
* :mod:`.cdr` and :mod:`.bag`: the byte codec's field columns and the bag extractors;
* :mod:`.topic_map` and :mod:`.live_inputs`: which channels a topic map may give;
* the simulator's noise, the estimator's input checks, alignment and replay columns.

Adding a channel on an existing topic is one entry in :data:`SENSOR` (appended: order is
the column order, the noise draw order and the bag digest's order), plus a producer
(the simulator's ``exact_samples``) and a consumer (a back-end or a feature set).
A σ or a bound of its own is a new :data:`NOISE` entry plus the sim node's
``sigma.<name>`` parameter, or a new estimator ``InputLimits`` field. A new topic or
message type also needs its message skeleton in :mod:`.messages`, its byte layout in
:mod:`.cdr` and its place in the estimator's alignment.

Units are SI, frames REP-103 (body frame at the CG: x forward, y left, z up, yaw
counter-clockwise). No rclpy, no rosbags: this module is plain data.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

from . import topics
from .errors import ContractError

KMH_TO_MPS: Final = 1.0 / 3.6


@dataclass(frozen=True, slots=True)
class NoiseKey:
    """One σ of :class:`~.sample.SensorNoiseSigma` (one Gaussian noise level, SI units).

    Attributes:
        name: the ``SensorNoiseSigma`` attribute (and the sim node's ``sigma.<name>``).
        unit: unit of σ.
        of: the channels it applies to, in words.
        paper: the paper's σ, converted to SI.
    """

    name: str
    unit: str
    of: str
    paper: float


@dataclass(frozen=True, slots=True)
class Channel:
    """One value of the contract and where the wire carries it.

    Attributes:
        name: sample attribute / column name, ending in its unit (``yaw_rate_radps``).
        symbol: the paper's symbol (X_v, ψ̇, ...).
        unit: SI unit.
        meaning: what it is, with frame and sign.
        topic: the contract topic (:mod:`.topics`) whose messages carry it.
        field: its field path in that topic's message (:mod:`.field_path` syntax).
        sigma: the :data:`NOISE` key of its sensor noise; None: published exact.
        limit: the plausibility bound beyond which a value is a sensor fault (the
            estimator's ``InputLimits`` attribute, ``limits.<limit>`` parameter); None:
            not checked (then also not a model input).
        feature_sets: the named feature sets (:mod:`.features`) that read it.
        model_input: a column of the estimator's window (``features.CHANNELS``); the
            channels a topic map may give.
        required: a message without this field is an error; else the value is NaN
            (real steering sensors often publish position only).
        rate_of: the channel it is the time derivative of; a topic map derives it by
            differencing that channel.
        lateral: changes sign when the car and its driving are mirrored left-right
            (lateral velocity and acceleration, yaw rate, steering); see :mod:`.mirror`.
    """

    name: str
    symbol: str
    unit: str
    meaning: str
    topic: str
    field: str
    sigma: str | None = None
    limit: str | None = None
    feature_sets: tuple[str, ...] = ()
    model_input: bool = True
    required: bool = True
    rate_of: str | None = None
    lateral: bool = False


NOISE: Final[tuple[NoiseKey, ...]] = (
    NoiseKey("velocity_mps", "m/s", "X_v and Y_v", 1.0 * KMH_TO_MPS),
    NoiseKey("acceleration_mps2", "m/s²", "X_a and Y_a", 0.1),
    NoiseKey("yaw_rate_radps", "rad/s", "ψ̇", math.radians(0.2)),
    NoiseKey("stl_m", "m", "the steering rack travel", 1.0e-3),
)
"""The sensor noise levels (the paper's: 1 km/h, 0.1 m/s², 0.2 deg/s, 1 mm)."""

_BOTH: Final = ("paper", "measurable")
_RACK: Final = f"[{topics.STEERING_JOINT}]"

SENSOR: Final[tuple[Channel, ...]] = (
    Channel(
        "x_v_mps", "X_v", "m/s", "longitudinal velocity, body frame at the CG",
        topics.TWIST, "twist.linear.x", "velocity_mps", "speed_mps", _BOTH,
    ),
    Channel(
        "y_v_mps", "Y_v", "m/s", "lateral velocity, body frame at the CG, positive left",
        topics.TWIST, "twist.linear.y", "velocity_mps", "speed_mps", ("paper",), lateral=True,
    ),
    Channel(
        "x_a_mps2", "X_a", "m/s²", "longitudinal acceleration at the CG",
        topics.IMU, "linear_acceleration.x", "acceleration_mps2", "acceleration_mps2", _BOTH,
    ),
    Channel(
        "y_a_mps2", "Y_a", "m/s²", "lateral acceleration at the CG, positive left",
        topics.IMU, "linear_acceleration.y", "acceleration_mps2", "acceleration_mps2", _BOTH,
        lateral=True,
    ),
    Channel(
        "yaw_rate_radps", "ψ̇", "rad/s", "yaw rate, counter-clockwise positive",
        topics.IMU, "angular_velocity.z", "yaw_rate_radps", "yaw_rate_radps", _BOTH,
        lateral=True,
    ),
    Channel(
        "stl_m", "STL", "m", "steering rack travel, positive steers left",
        topics.STEERING, f"position{_RACK}", "stl_m", "stl_m", _BOTH, lateral=True,
    ),
    Channel(
        "stl_rate_mps", "STL rate", "m/s", "steering rack speed (no model input)",
        topics.STEERING, f"velocity{_RACK}", model_input=False, required=False, rate_of="stl_m",
        lateral=True,
    ),
)  # fmt: skip
"""The sensor channels, in sample field order (= window column order of the inputs)."""

TRUTH: Final[tuple[Channel, ...]] = (
    Channel(
        "truth_v_x_mps", "v_x", "m/s", "exact longitudinal velocity at the CG",
        topics.GROUND_TRUTH_TWIST, "twist.linear.x", model_input=False,
    ),
    Channel(
        "truth_v_y_mps", "v_y", "m/s", "exact lateral velocity at the CG, positive left",
        topics.GROUND_TRUTH_TWIST, "twist.linear.y", model_input=False, lateral=True,
    ),
    Channel(
        "truth_yaw_rate_radps", "ψ̇", "rad/s", "exact yaw rate",
        topics.GROUND_TRUTH_TWIST, "twist.angular.z", model_input=False, lateral=True,
    ),
)  # fmt: skip
"""The ground-truth channels (simulator only): ``GroundTruth``'s fields with ``truth_``."""

TRUTH_PREFIX: Final = "truth_"


class ChannelRegistryError(ContractError, ValueError):
    """The registry contradicts itself (names the channel and the entry at fault)."""


def on_topic(topic: str) -> tuple[Channel, ...]:
    """The channels ``topic`` carries, in registry order (sensor, then truth)."""
    return tuple(ch for ch in (*SENSOR, *TRUTH) if ch.topic == topic)


def channel(name: str) -> Channel:
    """The channel named ``name`` (raises :class:`ChannelRegistryError` when unknown)."""
    for ch in (*SENSOR, *TRUTH):
        if ch.name == name:
            return ch
    raise ChannelRegistryError(f"unknown channel {name!r}")


def describe(channels: tuple[Channel, ...]) -> str:
    """Docstring lines ``name: symbol [unit] meaning`` (the records' Attributes)."""
    return "\n".join(f"        {c.name}: {c.meaning}, {c.symbol} [{c.unit}]." for c in channels)


def validate() -> None:
    """Check the registry (called when :mod:`.sample` derives its records from it)."""
    seen: list[str] = []
    noise = {n.name for n in NOISE}
    for ch in (*SENSOR, *TRUTH):
        where = f"channels: {ch.name}"
        if ch.name in seen or not ch.name.isidentifier():
            raise ChannelRegistryError(f"{where}: name repeated or not an identifier")
        home = topics.SENSOR_TOPICS if ch in SENSOR else (topics.GROUND_TRUTH_TWIST,)
        if ch.topic not in home:
            raise ChannelRegistryError(f"{where}: {ch.topic} is not one of {home}")
        if ch.sigma is not None and ch.sigma not in noise:
            raise ChannelRegistryError(f"{where}: sigma {ch.sigma!r} is not in NOISE")
        if ch.model_input and (ch.limit is None or ch not in SENSOR):
            raise ChannelRegistryError(f"{where}: a model input needs a limit (and is a sensor)")
        if ch.feature_sets and not ch.model_input:
            raise ChannelRegistryError(f"{where}: in feature sets but not a model input")
        if ch.rate_of is not None and ch.rate_of not in seen:
            raise ChannelRegistryError(f"{where}: rate_of {ch.rate_of!r} must come before it")
        if ch.rate_of is not None and ch.lateral != channel(ch.rate_of).lateral:
            raise ChannelRegistryError(f"{where}: lateral must match {ch.rate_of}'s")
        if (ch in TRUTH) != ch.name.startswith(TRUTH_PREFIX):
            raise ChannelRegistryError(f"{where}: truth channels (only) start {TRUTH_PREFIX!r}")
        seen.append(ch.name)
