"""Messages the estimator publishes (/sideslip, /sideslip/twist, /sideslip/status) and
/clock, built with either message back-end (:mod:`sideslip_msgs_py.messages` factories).

Field meanings, units and covariances are in each builder's docstring.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Final

import numpy as np

from . import topics
from .messages import (
    UNMEASURED_VARIANCE,
    MessageFactory,
    header,
    stamp_to_sec_nanosec,
    vector3,
)

DIAGNOSTIC_OK: Final = 0
DIAGNOSTIC_WARN: Final = 1
DIAGNOSTIC_ERROR: Final = 2
DIAGNOSTIC_STALE: Final = 3
"""diagnostic_msgs/DiagnosticStatus levels."""


def sideslip_message(factory: MessageFactory, beta_rad: float) -> Any:
    """``/sideslip``: std_msgs/Float64 with the estimated β [rad]."""
    return factory.Float64(data=float(beta_rad))


def sideslip_twist_message(
    factory: MessageFactory,
    stamp_ns: int,
    v_x_mps: float,
    beta_rad: float,
    beta_variance_rad2: float,
    v_x_variance_m2ps2: float,
) -> Any:
    """``/sideslip/twist``: v_x and v_y = v_x·tan β̂ with covariance, stamped with the input.

    See :func:`fill_sideslip_twist` for the fields; this builds a new message.
    """
    msg = factory.TwistWithCovarianceStamped(
        header=header(factory, 0),
        twist=factory.TwistWithCovariance(
            twist=factory.Twist(linear=vector3(factory), angular=vector3(factory)),
            covariance=np.zeros(36),
        ),
    )
    return fill_sideslip_twist(
        msg, stamp_ns, v_x_mps, beta_rad, beta_variance_rad2, v_x_variance_m2ps2
    )


def fill_sideslip_twist(
    msg: Any,
    stamp_ns: int,
    v_x_mps: float,
    beta_rad: float,
    beta_variance_rad2: float,
    v_x_variance_m2ps2: float,
) -> Any:
    """Write one estimate into a TwistWithCovarianceStamped (either back-end) and return it.

    A node reuses one message: building the nested message anew costs ~50 µs in rclpy,
    a fifth of the estimator's budget per 400-Hz sample.

    Fields: ``header.stamp`` = the input sample's stamp, ``frame_id`` = base_link;
    linear.x = v_x, linear.y = v_x·tan β̂, everything else 0. Covariance (row-major 6×6
    over x, y, z, roll, pitch, yaw of the twist): var(v_x) as given; var(v_y) by
    first-order propagation of v_y = v_x tan β, (v_x sec²β)²·var(β) + tan²β·var(v_x);
    cov(v_x, v_y) = tan β·var(v_x). The four components the estimator does not provide
    (v_z and the angular rates) carry :data:`UNMEASURED_VARIANCE`, so robot_localization
    gives them no weight.
    """
    sec, nanosec = stamp_to_sec_nanosec(stamp_ns)
    msg.header.stamp.sec = sec
    msg.header.stamp.nanosec = nanosec
    msg.header.frame_id = topics.BASE_FRAME
    tan_b = math.tan(beta_rad)
    sec2 = 1.0 + tan_b * tan_b
    twist = msg.twist.twist
    twist.linear.x = float(v_x_mps)
    twist.linear.y = float(v_x_mps * tan_b)
    cov = np.zeros(36)
    cov[0] = v_x_variance_m2ps2
    cov[1] = cov[6] = tan_b * v_x_variance_m2ps2
    cov[7] = (v_x_mps * sec2) ** 2 * beta_variance_rad2 + tan_b * tan_b * v_x_variance_m2ps2
    cov[14] = cov[21] = cov[28] = cov[35] = UNMEASURED_VARIANCE
    msg.twist.covariance = cov
    return msg


def status_message(
    factory: MessageFactory,
    stamp_ns: int,
    *,
    level: int,
    name: str,
    message: str,
    hardware_id: str,
    values: Mapping[str, object],
) -> Any:
    """``/sideslip/status``: a DiagnosticArray holding one DiagnosticStatus.

    ``values`` become KeyValue pairs (``str()`` of each value, in the given order).
    """
    status = factory.DiagnosticStatus(
        level=factory.diagnostic_level(level),
        name=name,
        message=message,
        hardware_id=hardware_id,
        values=[factory.KeyValue(key=str(k), value=str(v)) for k, v in values.items()],
    )
    return factory.DiagnosticArray(header=header(factory, stamp_ns, frame_id=""), status=[status])


def clock_message(factory: MessageFactory, stamp_ns: int) -> Any:
    """``/clock``: rosgraph_msgs/Clock holding the simulated time [ns]."""
    sec, nanosec = stamp_to_sec_nanosec(stamp_ns)
    return factory.Clock(clock=factory.Time(sec=sec, nanosec=nanosec))
