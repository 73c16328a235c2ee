"""Reference paths and the path-following driver.

Paths are dense polylines in the world frame (start at the origin heading +X, X forward,
Y left). The driver is a pure-pursuit controller on the rear-axle point with a
speed-proportional look-ahead, plus the understeer feed-forward of the linear
single-track model (pure pursuit alone is kinematic and cuts corners at speed), and a
steering-rate limit that keeps it human-like. It runs at the 400-Hz sample rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

PATH_SPACING_M = 0.25


@dataclass(frozen=True)
class DriverParams:
    """Pure-pursuit settings. Look-ahead = max(min, time × speed)."""

    lookahead_time_s: float = 0.6
    lookahead_min_m: float = 4.0
    max_road_wheel_rate_radps: float = 0.8  # ~ 700 deg/s at the hand wheel for a 15:1 ratio

    def as_array(self, understeer_gradient: float) -> np.ndarray:
        return np.array(
            [self.lookahead_time_s, self.lookahead_min_m, self.max_road_wheel_rate_radps,
             understeer_gradient]
        )  # fmt: skip


class PathBuilder:
    """Appends straight, lateral-offset and arc pieces to one continuous polyline."""

    def __init__(self) -> None:
        self._x = [0.0]
        self._y = [0.0]
        self._heading = 0.0

    def _append_local(self, s: np.ndarray, lateral: np.ndarray, heading_end: float) -> None:
        """Append points given in the frame of the current end point and heading."""
        c, sn = math.cos(self._heading), math.sin(self._heading)
        x0, y0 = self._x[-1], self._y[-1]
        self._x.extend((x0 + c * s - sn * lateral)[1:].tolist())
        self._y.extend((y0 + sn * s + c * lateral)[1:].tolist())
        self._heading = heading_end

    def straight(self, length_m: float) -> PathBuilder:
        n = max(2, math.ceil(length_m / PATH_SPACING_M) + 1)
        s = np.linspace(0.0, length_m, n)
        self._append_local(s, np.zeros(n), self._heading)
        return self

    def lane_change(self, length_m: float, offset_m: float) -> PathBuilder:
        """Move sideways by offset_m (> 0 left) over length_m with a smooth cosine ramp.

        The heading of the path returns to the entry heading at the end of the ramp.
        """
        n = max(2, math.ceil(length_m / PATH_SPACING_M) + 1)
        s = np.linspace(0.0, length_m, n)
        lateral = offset_m * 0.5 * (1.0 - np.cos(np.pi * s / length_m))
        self._append_local(s, lateral, self._heading)
        return self

    def arc(self, radius_m: float, angle_rad: float) -> PathBuilder:
        """Circular arc; angle_rad > 0 turns left."""
        length = radius_m * abs(angle_rad)
        n = max(2, math.ceil(length / PATH_SPACING_M) + 1)
        phi = np.linspace(0.0, abs(angle_rad), n)
        side = 1.0 if angle_rad > 0 else -1.0
        s = radius_m * np.sin(phi)
        lateral = side * radius_m * (1.0 - np.cos(phi))
        self._append_local(s, lateral, self._heading + angle_rad)
        return self

    def build(self) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(self._x), np.asarray(self._y)

    @property
    def length_m(self) -> float:
        x, y = self.build()
        return float(np.sum(np.hypot(np.diff(x), np.diff(y))))


def iso_double_lane_change(
    builder: PathBuilder, offset_m: float, length_scale: float = 1.0
) -> PathBuilder:
    """ISO 3888-1-like course: 15 m entry, 30 m change, 25 m offset lane, 25 m return,
    15 m exit, every length times length_scale. offset_m > 0 changes to the left first
    (3.5 m is the standard offset)."""
    k = length_scale
    return (
        builder.straight(15.0 * k)
        .lane_change(30.0 * k, offset_m)
        .straight(25.0 * k)
        .lane_change(25.0 * k, -offset_m)
        .straight(15.0 * k)
    )


@njit(cache=True, error_model="numpy")
def pure_pursuit(
    x_m: float,
    y_m: float,
    psi_rad: float,
    speed_mps: float,
    wheelbase_m: float,
    rear_axle_m: float,
    path_x: np.ndarray,
    path_y: np.ndarray,
    start_index: int,
    cfg: np.ndarray,
) -> tuple[float, int]:
    """Mean road-wheel angle [rad] that steers the rear axle onto the path.

    Returns (δ, index of the nearest path point) so the next call searches forward
    from there. Past the end of the path the target continues along its last heading.
    """
    rx = x_m - rear_axle_m * math.cos(psi_rad)
    ry = y_m - rear_axle_m * math.sin(psi_rad)
    n = path_x.shape[0]
    # Nearest point, searching forward in a bounded window: the path never doubles back
    # and the car covers < 0.3 m (~1 point) per 2.5-ms step below 400 km/h.
    best = start_index
    best_d2 = (path_x[best] - rx) ** 2 + (path_y[best] - ry) ** 2
    stop = min(n, start_index + 40)
    for k in range(start_index + 1, stop):
        d2 = (path_x[k] - rx) ** 2 + (path_y[k] - ry) ** 2
        if d2 < best_d2:
            best_d2 = d2
            best = k
    lookahead = max(cfg[1], cfg[0] * abs(speed_mps))
    target = -1
    for k in range(best, n):
        if (path_x[k] - rx) ** 2 + (path_y[k] - ry) ** 2 >= lookahead * lookahead:
            target = k
            break
    if target > best:
        # Interpolate on the segment that crosses the look-ahead circle, so the target
        # moves continuously rather than point to point (no steering chatter).
        ax = path_x[target - 1] - rx
        ay = path_y[target - 1] - ry
        dx = path_x[target] - path_x[target - 1]
        dy = path_y[target] - path_y[target - 1]
        qa = dx * dx + dy * dy
        qb = ax * dx + ay * dy
        qc = ax * ax + ay * ay - lookahead * lookahead
        frac = (-qb + math.sqrt(max(qb * qb - qa * qc, 0.0))) / qa if qa > 0.0 else 1.0
        frac = min(max(frac, 0.0), 1.0)
        tx = path_x[target - 1] + frac * dx
        ty = path_y[target - 1] + frac * dy
    elif target >= 0:
        tx = path_x[target]
        ty = path_y[target]
    else:
        hx = path_x[n - 1] - path_x[n - 2]
        hy = path_y[n - 1] - path_y[n - 2]
        norm = math.sqrt(hx * hx + hy * hy)
        tx = path_x[n - 1] + hx / norm * lookahead
        ty = path_y[n - 1] + hy / norm * lookahead
    eta = math.atan2(ty - ry, tx - rx) - psi_rad
    eta = math.atan2(math.sin(eta), math.cos(eta))
    kinematic = math.atan(2.0 * wheelbase_m * math.sin(eta) / lookahead)
    # Understeer feed-forward: δ = L/R + K a_y with a_y = u^2/R, so δ_kin (1 + K u^2 / L).
    gain = 1.0 + cfg[3] * speed_mps * speed_mps / wheelbase_m
    return kinematic * gain, best
