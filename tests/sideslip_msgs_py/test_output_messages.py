"""The estimator's outputs and /clock: /sideslip, /sideslip/twist, /sideslip/status, built
alike by both message back-ends, and serialisable as the contract's types."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py import topics
from sideslip_msgs_py.errors import MessageFieldError
from sideslip_msgs_py.messages import (
    NS_PER_S,
    UNMEASURED_VARIANCE,
    RclpyMessages,
    TypestoreMessages,
    stamp_ns,
    stamp_to_sec_nanosec,
)
from sideslip_msgs_py.outputs import (
    DIAGNOSTIC_ERROR,
    DIAGNOSTIC_OK,
    DIAGNOSTIC_STALE,
    DIAGNOSTIC_WARN,
    clock_message,
    sideslip_message,
    sideslip_twist_message,
    status_message,
)

RCLPY = RclpyMessages()
TYPESTORE = TypestoreMessages()
STORE = TYPESTORE.typestore
T_NS = 1_700_000_123_456_789_012

speeds = st.floats(0.0, 100.0)
betas = st.floats(-1.5, 1.5)  # |β| < 86°
variances = st.floats(0.0, 10.0)
stamps = st.integers(-(2**31) * NS_PER_S, 2**31 * NS_PER_S - 1)  # Time.sec is int32


def _round_trip(msg: Any) -> Any:
    """Serialise a typestore message with rosbags' serialize_cdr and read it back."""
    raw = STORE.serialize_cdr(msg, msg.__msgtype__)
    return STORE.deserialize_cdr(raw, msg.__msgtype__)


def _cov(msg: Any) -> np.ndarray:
    return np.asarray(msg.twist.covariance, dtype=float).reshape(6, 6)


# --- /sideslip --------------------------------------------------------------------------------


@pytest.mark.parametrize("factory", [RCLPY, TYPESTORE], ids=["rclpy", "typestore"])
def test_sideslip_message_carries_beta_in_radians(factory: Any) -> None:
    msg = sideslip_message(factory, np.float64(-0.0123))
    assert msg.data == -0.0123 and type(msg.data) is float


def test_sideslip_message_has_the_contract_type() -> None:
    msg = sideslip_message(TYPESTORE, 0.05)
    assert msg.__msgtype__ == topics.TOPIC_TYPES[topics.SIDESLIP]
    assert _round_trip(msg).data == 0.05


# --- /sideslip/twist --------------------------------------------------------------------------


def test_twist_v_y_is_v_x_tan_beta_stamped_with_the_input_in_base_link() -> None:
    msg = sideslip_twist_message(TYPESTORE, T_NS, 25.0, 0.04, 1e-4, 0.077)
    lin = msg.twist.twist.linear
    assert lin.x == 25.0 and lin.y == 25.0 * math.tan(0.04) and lin.z == 0.0
    ang = msg.twist.twist.angular
    assert (ang.x, ang.y, ang.z) == (0.0, 0.0, 0.0)
    assert stamp_ns(msg) == T_NS and msg.header.frame_id == topics.BASE_FRAME
    assert math.atan2(lin.y, lin.x) == pytest.approx(0.04, abs=1e-15)


def test_twist_covariance_is_the_documented_first_order_propagation() -> None:
    v_x, beta, var_b, var_vx = 20.0, 0.1, 4e-4, 0.0772
    cov = _cov(sideslip_twist_message(TYPESTORE, T_NS, v_x, beta, var_b, var_vx))
    t = math.tan(beta)
    assert cov[0, 0] == var_vx
    assert cov[1, 1] == pytest.approx((v_x * (1 + t * t)) ** 2 * var_b + t * t * var_vx)
    assert cov[0, 1] == cov[1, 0] == pytest.approx(t * var_vx)
    np.testing.assert_array_equal(np.diag(cov)[2:], [UNMEASURED_VARIANCE] * 4)
    off = cov.copy()
    np.fill_diagonal(off, 0.0)
    off[0, 1] = off[1, 0] = 0.0
    assert not off.any()  # nothing correlates with the components we do not provide


def test_twist_at_zero_beta_has_independent_components() -> None:
    cov = _cov(sideslip_twist_message(TYPESTORE, T_NS, 30.0, 0.0, 1e-4, 0.05))
    assert cov[0, 1] == 0.0 and cov[1, 1] == pytest.approx(900.0 * 1e-4)


@settings(max_examples=300, deadline=None)
@given(v_x=speeds, beta=betas, var_b=variances, var_vx=variances)
def test_twist_covariance_is_symmetric_positive_semidefinite(
    v_x: float, beta: float, var_b: float, var_vx: float
) -> None:
    cov = _cov(sideslip_twist_message(TYPESTORE, 0, v_x, beta, var_b, var_vx))
    np.testing.assert_array_equal(cov, cov.T)
    assert np.all(np.isfinite(cov))
    block = cov[:2, :2]
    scale = max(float(np.abs(block).max()), 1e-300)
    assert np.linalg.eigvalsh(block).min() >= -1e-12 * scale
    assert np.linalg.eigvalsh(cov).min() >= -1e-12 * float(np.abs(cov).max())


@settings(max_examples=100, deadline=None)
@given(stamp=stamps, v_x=speeds, beta=betas, var_b=variances, var_vx=variances)
def test_both_factories_build_the_same_twist(
    stamp: int, v_x: float, beta: float, var_b: float, var_vx: float
) -> None:
    a = sideslip_twist_message(RCLPY, stamp, v_x, beta, var_b, var_vx)
    b = sideslip_twist_message(TYPESTORE, stamp, v_x, beta, var_b, var_vx)
    assert (a.header.stamp.sec, a.header.stamp.nanosec) == (
        b.header.stamp.sec,
        b.header.stamp.nanosec,
    )
    assert a.header.frame_id == b.header.frame_id
    for part in ("linear", "angular"):
        va, vb = getattr(a.twist.twist, part), getattr(b.twist.twist, part)
        assert (va.x, va.y, va.z) == (vb.x, vb.y, vb.z)
    np.testing.assert_array_equal(np.asarray(a.twist.covariance), b.twist.covariance)


def test_typestore_twist_serialises_as_the_contract_type() -> None:
    msg = sideslip_twist_message(TYPESTORE, T_NS, 25.0, -0.03, 1e-4, 0.077)
    assert msg.__msgtype__ == topics.TOPIC_TYPES[topics.SIDESLIP_TWIST]
    back = _round_trip(msg)
    assert stamp_ns(back) == T_NS and back.twist.twist.linear.y == msg.twist.twist.linear.y
    np.testing.assert_array_equal(back.twist.covariance, msg.twist.covariance)


def test_rclpy_twist_serialises() -> None:
    from rclpy.serialization import deserialize_message, serialize_message

    msg = sideslip_twist_message(RCLPY, T_NS, 25.0, -0.03, 1e-4, 0.077)
    back = deserialize_message(serialize_message(msg), RCLPY.TwistWithCovarianceStamped)
    assert back == msg


# --- /sideslip/status -------------------------------------------------------------------------

VALUES = {"backend": "kinematic", "window_fill": "100/100", "estimates": 42, "p50": 0.125}


def _status(factory: Any, level: int) -> Any:
    return status_message(
        factory,
        T_NS,
        level=level,
        name="sideslip_estimator: sideslip estimate",
        message="estimating",
        hardware_id="/sideslip_estimator",
        values=VALUES,
    )


@pytest.mark.parametrize(
    "level", [DIAGNOSTIC_OK, DIAGNOSTIC_WARN, DIAGNOSTIC_ERROR, DIAGNOSTIC_STALE]
)
def test_status_level_is_a_byte_for_rclpy_and_an_int_for_rosbags(level: int) -> None:
    from diagnostic_msgs.msg import DiagnosticStatus

    rclpy_level = _status(RCLPY, level).status[0].level
    assert rclpy_level == bytes([level])
    typestore_level = _status(TYPESTORE, level).status[0].level
    assert typestore_level == level and type(typestore_level) is int
    names = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}
    assert getattr(DiagnosticStatus, names[level]) == rclpy_level


@pytest.mark.parametrize("factory", [RCLPY, TYPESTORE], ids=["rclpy", "typestore"])
def test_status_holds_one_status_with_string_values_in_order(factory: Any) -> None:
    msg = _status(factory, DIAGNOSTIC_WARN)
    assert len(msg.status) == 1
    s = msg.status[0]
    assert s.name == "sideslip_estimator: sideslip estimate"
    assert s.message == "estimating" and s.hardware_id == "/sideslip_estimator"
    assert [(kv.key, kv.value) for kv in s.values] == [
        ("backend", "kinematic"),
        ("window_fill", "100/100"),
        ("estimates", "42"),
        ("p50", "0.125"),
    ]
    assert stamp_ns(msg) == T_NS and msg.header.frame_id == ""


def test_typestore_status_serialises_as_the_contract_type() -> None:
    msg = _status(TYPESTORE, DIAGNOSTIC_ERROR)
    assert msg.__msgtype__ == topics.TOPIC_TYPES[topics.SIDESLIP_STATUS]
    back = _round_trip(msg)
    assert back.status[0].level == DIAGNOSTIC_ERROR
    assert [kv.value for kv in back.status[0].values] == ["kinematic", "100/100", "42", "0.125"]


def test_rclpy_status_serialises() -> None:
    from rclpy.serialization import deserialize_message, serialize_message

    msg = _status(RCLPY, DIAGNOSTIC_WARN)
    assert deserialize_message(serialize_message(msg), RCLPY.DiagnosticArray) == msg


# --- /clock and stamps ---------------------------------------------------------------------------


@settings(max_examples=300, deadline=None)
@given(stamps)
def test_sec_nanosec_round_trip_for_any_representable_stamp(stamp: int) -> None:
    sec, nanosec = stamp_to_sec_nanosec(stamp)
    assert 0 <= nanosec < NS_PER_S
    assert sec * NS_PER_S + nanosec == stamp


@settings(max_examples=100, deadline=None)
@given(stamps)
def test_clock_message_round_trips_the_stamp_in_both_factories(stamp: int) -> None:
    for factory in (RCLPY, TYPESTORE):
        clock = clock_message(factory, stamp).clock
        assert clock.sec * NS_PER_S + clock.nanosec == stamp
    back = _round_trip(clock_message(TYPESTORE, stamp)).clock
    assert back.sec * NS_PER_S + back.nanosec == stamp


def test_clock_message_has_the_contract_type() -> None:
    assert clock_message(TYPESTORE, T_NS).__msgtype__ == topics.TOPIC_TYPES[topics.CLOCK]


@pytest.mark.parametrize("stamp", [2**31 * NS_PER_S, -(2**31) * NS_PER_S - 1])
def test_stamp_beyond_int32_seconds_is_refused(stamp: int) -> None:
    with pytest.raises(MessageFieldError, match="int32"):
        clock_message(TYPESTORE, stamp)
    with pytest.raises(MessageFieldError, match="int32"):
        sideslip_twist_message(TYPESTORE, stamp, 20.0, 0.0, 0.0, 0.0)
