"""Input checks and alignment of the three sensor streams on the IMU stamp.

Each sensor topic arrives on its own; a model sample is formed when an IMU message
arrives, from its accelerations and yaw rate plus the latest twist and steering
values, as DESIGN.md says. A sample is rejected (never passed on) when one of those
inputs is missing, older than ``max_input_age_s`` relative to the IMU stamp, or a
message held a non-finite or physically absurd value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.features import CHANNELS, channel_indices
from sideslip_msgs_py.messages import NS_PER_S, ImuFields, SteeringFields, TwistFields

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


def check_imu(topic: str, f: ImuFields, limits: InputLimits) -> None:
    """Raise :class:`InputRejected` naming the field when an IMU value is unusable."""
    _check(topic, "linear_acceleration.x", f.x_a_mps2, limits.acceleration_mps2)
    _check(topic, "linear_acceleration.y", f.y_a_mps2, limits.acceleration_mps2)
    _check(topic, "angular_velocity.z", f.yaw_rate_radps, limits.yaw_rate_radps)


def check_twist(topic: str, f: TwistFields, limits: InputLimits) -> None:
    _check(topic, "twist.linear.x", f.x_v_mps, limits.speed_mps)
    _check(topic, "twist.linear.y", f.y_v_mps, limits.speed_mps)


def check_steering(topic: str, f: SteeringFields, limits: InputLimits) -> None:
    # The rate is not a model input; a missing (NaN) rate is normal for real sensors.
    _check(topic, "position[steering_rack]", f.stl_m, limits.stl_m)


class Aligner:
    """Holds the latest twist and steering and forms a sample on each IMU message."""

    def __init__(self, max_input_age_s: float) -> None:
        if not (math.isfinite(max_input_age_s) and max_input_age_s > 0.0):
            msg = f"max_input_age_s must be finite and > 0, got {max_input_age_s!r}"
            raise ValueError(msg)
        self.max_age_ns = round(max_input_age_s * NS_PER_S)
        self.twist: TwistFields | None = None
        self.steering: SteeringFields | None = None
        self._row = np.zeros(len(CHANNELS))

    def forget_after(self, imu_stamp_ns: int) -> None:
        """Drop held inputs stamped later than ``imu_stamp_ns`` + the age limit: after a
        stamp jump backwards they belong to the old time line."""
        limit = imu_stamp_ns + self.max_age_ns
        if self.twist is not None and self.twist.stamp_ns > limit:
            self.twist = None
        if self.steering is not None and self.steering.stamp_ns > limit:
            self.steering = None

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
        if self.twist is None:
            raise InputRejected("no_twist", "no twist received yet")
        if self.steering is None:
            raise InputRejected("no_steering", "no steering received yet")
        self._age_ok("twist", imu.stamp_ns, self.twist.stamp_ns)
        self._age_ok("steering", imu.stamp_ns, self.steering.stamp_ns)
        row = self._row
        row[X_V] = self.twist.x_v_mps
        row[Y_V] = self.twist.y_v_mps
        row[X_A] = imu.x_a_mps2
        row[Y_A] = imu.y_a_mps2
        row[YAW_RATE] = imu.yaw_rate_radps
        row[STL] = self.steering.stl_m
        return row
