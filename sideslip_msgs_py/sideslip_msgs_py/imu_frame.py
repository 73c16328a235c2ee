"""A body-frame accelerometer's reading turned into the contract's level acceleration at
the CG.

The contract's X_a, Y_a (and every model's inputs) are the CG acceleration in the
horizontal, yaw-aligned vehicle frame, free of gravity (docs/vehicle-model.md). A
``sensor_msgs/Imu`` from a strapdown IMU carries specific force in the body frame with
gravity in it (REP 145): in a turn the body rolls and Y_a reads a_y·cos φ + g·sin φ,
under braking it pitches and X_a reads a_x·cos θ − g·sin θ. With the body's roll φ and
pitch θ (an AHRS or INS orientation, ``imu.attitude`` of a topic map) the inverse is

    a_y = (f_y − g·sin φ) / cos φ,   a_x = (f_x + g·sin θ) / cos θ,

exact for the simulator's body-frame IMU (``sideslip_sim.imu_mounting``, which leaves
out the products of roll and pitch) and, for a real one, as long as the car does not
accelerate vertically. Frames are REP 103's: x forward, y left, z up; a positive roll
lifts the left side (the body leans right, as in a left turn), a positive pitch is nose
down, which is what a quaternion's roll about x and pitch about y give in that frame.

An IMU at (x, y) from the CG also reads the lever arm of the car's yaw motion,
ṙ·x − r²·y on Y_a and −ṙ·y − r²·x on X_a (:func:`at_cg` takes it out, with ṙ from the
yaw rate by :class:`YawAcceleration`, causal so that bags and the live node agree).
"""

from __future__ import annotations

import math
from typing import Any, Final, TypeVar

import numpy as np
import numpy.typing as npt

from .model_inputs import GRAVITY_MPS2

MAX_TILT_RAD: Final = math.radians(45.0)
"""A roll or pitch beyond this is no car on a road: the sample is NaN (not a division
by a cosine near 0)."""

Values = TypeVar("Values", float, npt.NDArray[np.float64])


def roll_pitch(quaternion: Any) -> tuple[float, float]:
    """Roll and pitch [rad] of a ``geometry_msgs/Quaternion`` (x, y, z, w; the body's
    orientation in a z-up world frame), as roll about x, then pitch about y (the
    aerospace Z-Y-X order, which is ROS's ``tf2`` RPY)."""
    x, y, z, w = (float(getattr(quaternion, k)) for k in ("x", "y", "z", "w"))
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(norm) or norm < 1e-9:
        raise ValueError(
            f"orientation quaternion ({x}, {y}, {z}, {w}) has no direction (an IMU without "
            "an orientation estimate publishes zeros: map another attitude source)"
        )
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    return roll, pitch


def level_accelerations(
    f_x: Values, f_y: Values, roll_rad: Values, pitch_rad: Values
) -> tuple[Values, Values]:
    """The level-frame CG accelerations (a_x, a_y) [m/s²] of a body-frame accelerometer's
    specific force (f_x, f_y) [m/s²] at roll and pitch [rad] (see module); NaN where the
    tilt exceeds :data:`MAX_TILT_RAD`."""
    scalar = all(isinstance(v, float) for v in (f_x, f_y, roll_rad, pitch_rad))
    # One formula for both: math on one live sample (numpy costs ~7 µs per call on the
    # node's 400-Hz path), numpy on a bag's columns.
    xp: Any = math if scalar else np
    roll, pitch = (v if scalar else np.asarray(v, dtype=float) for v in (roll_rad, pitch_rad))
    a_x = (f_x + GRAVITY_MPS2 * xp.sin(pitch)) / xp.cos(pitch)
    a_y = (f_y - GRAVITY_MPS2 * xp.sin(roll)) / xp.cos(roll)
    tilted = (abs(roll) > MAX_TILT_RAD) | (abs(pitch) > MAX_TILT_RAD)
    if scalar:
        return (math.nan, math.nan) if tilted else (a_x, a_y)  # type: ignore[return-value]
    return np.where(tilted, np.nan, a_x), np.where(tilted, np.nan, a_y)  # type: ignore[return-value]


LEVER_ARM_TIME_CONSTANT_S: Final = 0.02
"""Time constant [s] of the causal first-order low-pass on the yaw acceleration for the
lever arm (a corner at 8 Hz). The yaw rate's noise differenced at 400 Hz is ~2 rad/s²;
a slower filter lags the step steers' ṙ (up to 4.5 rad/s²). On validation cars 0–3's
μ = 1 benchmark-style drives (paper noise) the RMS error of ṙ was 0.23 rad/s² at 8 Hz,
0.27 at 5 Hz, 0.26 at 12 Hz, 0.50 at 2 Hz (a second-order Butterworth: 0.24 at 8 Hz)."""
MAX_STEP_S: Final = 0.1
"""A longer step between samples (or one back in time) starts the derivative afresh."""


class YawAcceleration:
    """ṙ [rad/s²] from yaw-rate samples one at a time, causal: the backward difference,
    low-passed with :data:`LEVER_ARM_TIME_CONSTANT_S`. The same object serves bags
    (:func:`yaw_accelerations`) and the live node, so both give the same samples."""

    def __init__(self, time_constant_s: float = LEVER_ARM_TIME_CONSTANT_S) -> None:
        self.time_constant_s = time_constant_s
        self._last: tuple[int, float] | None = None
        self._value = 0.0

    def update(self, stamp_ns: int, yaw_rate_radps: float) -> float:
        """The filtered ṙ at this sample (0 at the first one and after a gap; NaN for a
        non-finite yaw rate, which leaves the state as it was)."""
        if not math.isfinite(yaw_rate_radps):
            return math.nan
        last, self._last = self._last, (stamp_ns, yaw_rate_radps)
        if last is None or not 0 < stamp_ns - last[0] <= MAX_STEP_S * 1e9:
            self._value = 0.0
            return 0.0
        dt = (stamp_ns - last[0]) * 1e-9
        raw = (yaw_rate_radps - last[1]) / dt
        self._value += dt / (self.time_constant_s + dt) * (raw - self._value)
        return self._value


def yaw_accelerations(
    stamps_ns: npt.NDArray[np.int64], yaw_rate_radps: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """:class:`YawAcceleration` over a whole series (a bag's)."""
    filt = YawAcceleration()
    return np.array(
        [filt.update(int(t), float(r)) for t, r in zip(stamps_ns, yaw_rate_radps, strict=True)]
    )


def at_cg(
    a_x: Values, a_y: Values, yaw_rate_radps: Values, yaw_accel_radps2: Values,
    position_m: tuple[float, float],
) -> tuple[Values, Values]:  # fmt: skip
    """The CG's level accelerations from those of a point at ``position_m`` (x forward,
    y left, from the CG [m]) of a car turning at r with ṙ (planar rigid body: the
    inverse of ``sideslip_sim.imu_mounting``'s lever arm)."""
    x, y = position_m
    r, r_dot = yaw_rate_radps, yaw_accel_radps2
    return a_x + r_dot * y + r * r * x, a_y - r_dot * x + r * r * y  # type: ignore[return-value]
