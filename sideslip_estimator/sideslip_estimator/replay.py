"""Drive the estimator core from recorded samples, as the node would: pure, no rclpy.

One home for the offline loop that the held-out benchmark, the UKF noise tuning and
``bench/offline_backends.py`` share: per step the twist, the steering, then the IMU
of the same stamp (so every IMU sample aligns with its own step), through the same
checks, alignment, window and back-end as the node.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py import topics
from sideslip_msgs_py.messages import ImuFields, SteeringFields, TwistFields
from sideslip_msgs_py.sample import SampleArrays

from .estimator import Estimator
from .inputs import InputRejected

REPLAY_COLUMNS = (
    "stamp_ns", "x_v_mps", "y_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m",
    "stl_rate_mps",
)  # fmt: skip
"""The sample columns the loop reads, in the order of :func:`replay_columns`' rows."""


@dataclass(frozen=True)
class Replayed:
    """β̂ [rad] per sample (NaN where none) and how many samples were rejected."""

    beta_rad: npt.NDArray[np.float64]
    rejected: int


def replay_columns(samples: SampleArrays) -> tuple[Sequence[float | int], ...]:
    """The samples as Python lists per column (converted once; the loop is per sample)."""
    return tuple(getattr(samples, c).tolist() for c in REPLAY_COLUMNS)


def replay(estimator: Estimator, columns: tuple[Sequence[float | int], ...]) -> Replayed:
    """Feed ``columns`` (from :func:`replay_columns`) through ``estimator``."""
    n = len(columns[0])
    beta = np.full(n, np.nan)
    rejected = 0
    rows = zip(*columns, strict=True)
    for i, (stamp, x_v, y_v, x_a, y_a, r, stl, stl_rate) in enumerate(rows):
        try:
            estimator.on_twist(topics.TWIST, TwistFields(stamp, x_v, y_v))
            estimator.on_steering(topics.STEERING, SteeringFields(stamp, stl, stl_rate))
            out = estimator.on_imu(topics.IMU, ImuFields(stamp, x_a, y_a, r))
        except InputRejected:
            rejected += 1
            continue
        if out is not None:
            beta[i] = out.estimate.beta_rad
    return Replayed(beta, rejected)
