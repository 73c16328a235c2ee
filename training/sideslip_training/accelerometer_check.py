"""Does the recorded Y_a mean what the models take it to mean? Checked against the reference.

Every model and the UKF read Y_a as the CG's lateral acceleration in the horizontal
frame, free of gravity (docs/vehicle-model.md). A recording with a reference velocity
fixes that quantity exactly: a_y = v̇_y + v_x·ψ̇ (body frame at the CG, the frame the
reference is moved to). The slope of the recorded Y_a over it is 1 for a right IMU:
0.998–1.000 on simulated recordings with paper noise (8 validation cars, 18 drives
each). It is not 1 when

- the IMU reads in the body frame with gravity in it (REP 145's ``sensor_msgs/Imu``)
  and nothing took the roll out: 1.09–1.13 on the same cars (every UKF-anchored model
  was about ten times worse then: docs/evaluation/imu-mounting);
- the accelerometer is in g instead of m/s² (≈ 0.10), or its y axis points right (< 0);
- the reference is not where the topic map says, or is in another frame.

:func:`check_accelerometer` measures the slope and offset on the runs' moving samples
(after a 2-Hz zero-phase low-pass of each channel: noise out, driving kept) and says
what to do when it is off by more than :data:`SCALE_TOLERANCE`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np

SCALE_TOLERANCE: Final = 0.03
"""|slope − 1| beyond this is reported: ten times the spread on simulated recordings,
and under the 4–6 % of gravity a stiff sports car's roll adds."""
MIN_SPEED_MPS: Final = 5.0
MIN_LATERAL_MPS2: Final = 1.0
"""Only samples that corner (|a_y| above this [m/s²]) fix the slope."""
MIN_POINTS: Final = 2000
"""Fewer usable samples than this (5 s at 400 Hz of cornering) give no check."""
CUTOFF_HZ: Final = 2.0


@dataclass(frozen=True)
class AccelerometerCheck:
    """The recorded Y_a against the reference's lateral acceleration.

    scale: slope of Y_a over v̇_y + v_x·ψ̇ [-] (1 for a right, gravity-free IMU).
    offset_mps2: the fit's intercept [m/s²] (a mounting tilt or a sensor bias).
    samples: samples the fit used.
    """

    scale: float
    offset_mps2: float
    samples: int

    @property
    def warning(self) -> str | None:
        """One line saying what looks wrong and what to change, or None."""
        s = self.scale
        head = (
            f"warning: Y_a is {s:.3f} × the lateral acceleration the reference implies "
            f"(v̇_y + X_v·ψ̇, {self.samples} samples)"
        )
        if s < 0.0:
            return f"{head}: its sign is reversed (a y axis to the right?): scale y_a_mps2 by -1"
        if 0.07 < s < 0.14:
            return f"{head}: Y_a looks like g, not m/s²: scale y_a_mps2 by 9.80665"
        if s > 1.0 + SCALE_TOLERANCE:
            return (
                f"{head}: an IMU reading in the body frame, with gravity through the car's "
                "roll? Map its orientation (topic map imu: {frame: body, attitude: ...}), or "
                f"scale y_a_mps2 by {1.0 / s:.3f} (docs/topic-maps.md)"
            )
        if s < 1.0 - SCALE_TOLERANCE:
            return (
                f"{head}: check the accelerometer's unit and the reference's frame and "
                f"position (topic map reference.position_m); scale y_a_mps2 by {1.0 / s:.3f} "
                "if the reference is right"
            )
        return None


def _smooth(x: np.ndarray, rate_hz: float) -> np.ndarray:
    from scipy.signal import butter, sosfiltfilt

    return sosfiltfilt(butter(2, CUTOFF_HZ, fs=rate_hz, output="sos"), x)


def check_accelerometer(runs: Sequence[Any]) -> AccelerometerCheck | None:
    """The check over ``runs`` (:class:`~.dataset.Run` records with a reference), or None
    when they hold too little cornering at speed (see module)."""
    xs, ys = [], []
    for run in runs:
        s = run.samples
        if s.truth_v_y_mps is None or len(s) < 30:
            continue
        t = (s.stamp_ns - s.stamp_ns[0]) * 1e-9
        columns = [s.truth_v_x_mps, s.truth_v_y_mps, s.y_a_mps2]
        r = s.truth_yaw_rate_radps if s.truth_yaw_rate_radps is not None else s.yaw_rate_radps
        columns.append(r)
        if not all(np.isfinite(c).all() for c in columns) or np.any(np.diff(t) <= 0):
            continue  # a stretch with holes is left out, not filtered across
        rate = 1.0 / float(np.median(np.diff(t)))
        if rate <= 2.5 * CUTOFF_HZ:
            continue
        u, v, f_y, r = (_smooth(np.asarray(c, dtype=float), rate) for c in columns)
        a_y = np.gradient(v, t) + u * r
        keep = (u > MIN_SPEED_MPS) & (np.abs(a_y) > MIN_LATERAL_MPS2)
        xs.append(a_y[keep])
        ys.append(f_y[keep])
    if not xs or sum(x.size for x in xs) < MIN_POINTS:
        return None
    x, y = np.concatenate(xs), np.concatenate(ys)
    scale, offset = np.linalg.lstsq(np.stack([x, np.ones_like(x)], axis=1), y, rcond=None)[0]
    return AccelerometerCheck(float(scale), float(offset), int(x.size))
