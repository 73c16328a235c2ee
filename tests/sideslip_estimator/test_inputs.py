"""Input checks (non-finite, absurd values) and alignment of twist and steering on the
IMU stamp."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sideslip_estimator.inputs import (
    Aligner,
    InputLimits,
    InputRejected,
    check_imu,
    check_steering,
    check_twist,
)
from sideslip_msgs_py.features import CHANNELS
from sideslip_msgs_py.messages import ImuFields, SteeringFields, TwistFields

MS = 1_000_000
LIMITS = InputLimits()
IMU = ImuFields(stamp_ns=0, x_a_mps2=0.3, y_a_mps2=-2.0, yaw_rate_radps=0.1)
TWIST = TwistFields(stamp_ns=0, x_v_mps=20.0, y_v_mps=-0.4)
STEER = SteeringFields(stamp_ns=0, stl_m=0.01, stl_rate_mps=0.002)

# (checker, good fields, attribute, field name in the message, limit)
FIELDS = [
    (check_imu, IMU, "x_a_mps2", "linear_acceleration.x", LIMITS.acceleration_mps2),
    (check_imu, IMU, "y_a_mps2", "linear_acceleration.y", LIMITS.acceleration_mps2),
    (check_imu, IMU, "yaw_rate_radps", "angular_velocity.z", LIMITS.yaw_rate_radps),
    (check_twist, TWIST, "x_v_mps", "twist.linear.x", LIMITS.speed_mps),
    (check_twist, TWIST, "y_v_mps", "twist.linear.y", LIMITS.speed_mps),
    (check_steering, STEER, "stl_m", "position[steering_rack]", LIMITS.stl_m),
]
FIELD_IDS = [f[2] for f in FIELDS]


@pytest.mark.parametrize(("check", "good", "attr", "field", "limit"), FIELDS, ids=FIELD_IDS)
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_value_in_any_field_is_rejected_naming_topic_and_field(
    check, good, attr, field, limit, bad
) -> None:
    with pytest.raises(InputRejected) as info:
        check("/some/topic", good._replace(**{attr: bad}), LIMITS)
    assert info.value.reason == "non_finite"
    assert "/some/topic" in str(info.value) and field in str(info.value)


@pytest.mark.parametrize(("check", "good", "attr", "field", "limit"), FIELDS, ids=FIELD_IDS)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_absurd_value_in_any_field_is_rejected_naming_topic_and_field(
    check, good, attr, field, limit, sign
) -> None:
    with pytest.raises(InputRejected) as info:
        check("/vehicle/x", good._replace(**{attr: sign * limit * 1.01}), LIMITS)
    assert info.value.reason == "out_of_range"
    assert "/vehicle/x" in str(info.value) and field in str(info.value)
    # The limit itself is still a plausible value.
    check("/vehicle/x", good._replace(**{attr: sign * limit}), LIMITS)


def test_good_messages_pass_the_checks() -> None:
    check_imu("/vehicle/imu", IMU, LIMITS)
    check_twist("/vehicle/twist", TWIST, LIMITS)
    check_steering("/vehicle/steering", STEER, LIMITS)


def test_missing_steering_rate_is_not_a_fault() -> None:
    # Real steering sensors often publish position only: the rate is NaN then.
    check_steering("/vehicle/steering", STEER._replace(stl_rate_mps=math.nan), LIMITS)


def test_input_rejected_is_a_value_error_with_a_short_reason() -> None:
    err = InputRejected("non_finite", "detail")
    assert isinstance(err, ValueError) and err.reason == "non_finite" and str(err) == "detail"


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf])
@pytest.mark.parametrize("name", ["speed_mps", "acceleration_mps2", "yaw_rate_radps", "stl_m"])
def test_input_limits_must_be_finite_and_positive(name: str, bad: float) -> None:
    with pytest.raises(ValueError, match=f"InputLimits.{name}"):
        InputLimits(**{name: bad})


def test_default_limits_are_beyond_what_a_road_car_reaches() -> None:
    assert LIMITS.speed_mps >= 300 / 3.6  # m/s
    assert LIMITS.acceleration_mps2 >= 3 * 9.81
    assert LIMITS.yaw_rate_radps >= math.radians(180.0)
    assert LIMITS.stl_m >= 0.2


# --- alignment -----------------------------------------------------------------------------


def _aligner(max_age_s: float = 0.05) -> Aligner:
    return Aligner(max_age_s)


def test_no_twist_yet_is_rejected_with_reason() -> None:
    a = _aligner()
    a.steering = STEER
    with pytest.raises(InputRejected) as info:
        a.sample(IMU)
    assert info.value.reason == "no_twist"


def test_no_steering_yet_is_rejected_with_reason() -> None:
    a = _aligner()
    a.twist = TWIST
    with pytest.raises(InputRejected) as info:
        a.sample(IMU)
    assert info.value.reason == "no_steering"


@pytest.mark.parametrize("which", ["twist", "steering"])
@pytest.mark.parametrize("offset_ms", [-51, 51, -5000, 5000])
def test_twist_or_steering_older_or_newer_than_max_age_is_rejected_as_stale(
    which: str, offset_ms: int
) -> None:
    a = _aligner(0.05)
    imu = IMU._replace(stamp_ns=10_000 * MS)
    current = {"twist": TWIST, "steering": STEER}
    for name, fields in current.items():
        shift = offset_ms * MS if name == which else 0
        setattr(a, name, fields._replace(stamp_ns=imu.stamp_ns - shift))
    with pytest.raises(InputRejected) as info:
        a.sample(imu)
    assert info.value.reason == f"stale_{which}"
    assert which in str(info.value) and "ms" in str(info.value)


@pytest.mark.parametrize("offset_ms", [-50, -2.5, 0, 2.5, 50])
def test_inputs_within_max_age_either_side_are_accepted(offset_ms: float) -> None:
    a = _aligner(0.05)
    imu = IMU._replace(stamp_ns=10_000 * MS)
    a.twist = TWIST._replace(stamp_ns=imu.stamp_ns - round(offset_ms * MS))
    a.steering = STEER._replace(stamp_ns=imu.stamp_ns + round(offset_ms * MS))
    a.sample(imu)


def test_sample_row_has_the_channels_in_contract_order_from_the_latest_values() -> None:
    a = _aligner()
    a.twist = TWIST._replace(x_v_mps=1.0)
    a.steering = STEER._replace(stl_m=0.4)
    a.twist = TWIST  # the latest value replaces the earlier one
    a.steering = STEER
    row = a.sample(IMU)
    expected = {
        "x_v_mps": TWIST.x_v_mps,
        "y_v_mps": TWIST.y_v_mps,
        "x_a_mps2": IMU.x_a_mps2,
        "y_a_mps2": IMU.y_a_mps2,
        "yaw_rate_radps": IMU.yaw_rate_radps,
        "stl_m": STEER.stl_m,
    }
    np.testing.assert_array_equal(row, [expected[c] for c in CHANNELS])


def test_forget_after_drops_inputs_from_a_later_time_line_only() -> None:
    a = _aligner()
    a.twist, a.steering = TWIST, STEER
    a.forget_after(IMU.stamp_ns)  # same time line: kept
    assert a.twist is TWIST and a.steering is STEER
    a.forget_after(TWIST.stamp_ns - 10**9)  # the IMU jumped a second back
    assert a.twist is None and a.steering is None
    with pytest.raises(InputRejected, match="no twist"):
        a.sample(IMU)


@pytest.mark.parametrize("bad", [0.0, -0.01, math.nan, math.inf])
def test_max_input_age_must_be_finite_and_positive(bad: float) -> None:
    with pytest.raises(ValueError, match="max_input_age_s"):
        Aligner(bad)


def test_the_input_of_the_imu_own_time_is_used_when_a_newer_one_has_arrived() -> None:
    # On a loaded machine the IMU message of step k may arrive after the twist of step
    # k + 3 (DDS does not order topics): the twist of step k is still the one used.
    a = _aligner(0.05)
    imu = IMU._replace(stamp_ns=10_000 * MS)
    for k in range(-2, 4):
        a.twist = TWIST._replace(stamp_ns=imu.stamp_ns + round(k * 2.5 * MS), x_v_mps=20.0 + k)
        a.steering = STEER._replace(stamp_ns=imu.stamp_ns + round(k * 2.5 * MS), stl_m=0.01 * k)
    row = a.sample(imu)
    assert row[CHANNELS.index("x_v_mps")] == 20.0 and row[CHANNELS.index("stl_m")] == 0.0
    # Only newer ones held (a clock slightly ahead): the nearest is used, within the age.
    b = _aligner(0.05)
    b.twist = TWIST._replace(stamp_ns=imu.stamp_ns + 10 * MS)
    b.steering = STEER._replace(stamp_ns=imu.stamp_ns + 5 * MS)
    b.sample(imu)
