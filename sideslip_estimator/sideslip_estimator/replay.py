"""Drive the estimator core from recorded samples, as the node would: pure, no rclpy.

One home for the offline loop that the held-out benchmark, the UKF noise tuning and
``bench/offline_backends.py`` share: per step the twist, the steering, then the IMU
of the same stamp (so every IMU sample aligns with its own step), through the same
checks, alignment, window and back-end as the node.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py import channels as registry
from sideslip_msgs_py import topics
from sideslip_msgs_py.messages import FIELDS_RECORDS
from sideslip_msgs_py.sample import SENSOR_CHANNELS, SampleArrays

from .estimator import Estimator
from .inputs import InputRejected

REPLAY_COLUMNS = ("stamp_ns", *SENSOR_CHANNELS)
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
    twists, steerings, imus = (
        _records(t, columns) for t in (topics.TWIST, topics.STEERING, topics.IMU)
    )
    for i, (twist, steering, imu) in enumerate(zip(twists, steerings, imus, strict=True)):
        try:
            estimator.on_twist(topics.TWIST, twist)
            estimator.on_steering(topics.STEERING, steering)
            out = estimator.on_imu(topics.IMU, imu)
        except InputRejected:
            rejected += 1
            continue
        if out is not None:
            beta[i] = out.estimate.beta_rad
    return Replayed(beta, rejected)


def _records(topic: str, columns: tuple[Sequence[float | int], ...]) -> Iterator[Any]:
    """``topic``'s fields record (``TwistFields``, ...) of every row, stamped as the row
    (made one row at a time, as the loop takes them)."""
    picked = [columns[REPLAY_COLUMNS.index(ch.name)] for ch in registry.on_topic(topic)]
    return map(FIELDS_RECORDS[topic]._make, zip(columns[0], *picked, strict=True))
