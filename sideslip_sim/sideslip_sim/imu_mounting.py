"""Where the IMU sits on the car and what its accelerometer reports.

The simulator's contract IMU is an ideal one: the whole-vehicle CG acceleration in the
horizontal, yaw-aligned vehicle frame (roll- and pitch-compensated, at the CG;
docs/vehicle-model.md). A real car's IMU is bolted to the body somewhere else, and an
unaided MEMS IMU or an ESC sensor cluster reports *specific force in the body frame*:
gravity's projection through the body's roll and pitch is in it, as ``sensor_msgs/Imu``
carries it by convention (REP 145: a resting IMU reads +9.81 m/s² up). In a left turn the
body rolls to the right, so the lateral channel reads a_y·cos φ + g·sin φ: at a roll
gradient of 5°/g that is 9 % more than a_y. :class:`ImuMounting` lets the simulator
publish such an IMU, so the estimators can be measured against it
(docs/evaluation/imu-mounting).

Frames (docs/vehicle-model.md): x forward, y left, z up; roll φ > 0 lifts the left side,
pitch θ > 0 is nose-down. The lever arm is planar: the IMU at (x, y) from the CG on a car
turning at yaw rate r with yaw acceleration ṙ sees

    a_x,P = a_x − ṙ·y − r²·x,   a_y,P = a_y + ṙ·x − r²·y

(its height adds roll- and pitch-rate terms of the sprung mass, not modelled). In the
body frame the accelerometer then reads

    f_x = (a_x,P − g_x)·cos θ − g·sin θ,   f_y = (a_y,P − g_y)·cos φ + g·sin φ

with g_x, g_y gravity's share in the plane of a banked road (0 on a level road; the
body's roll and pitch are the suspension's, relative to the road; the cross terms
between roll and pitch, products of two small angles, are left out).
The gyro is taken to read the yaw rate r: in the body frame it reads r·cos φ·cos θ plus
roll- and pitch-rate terms, under 0.5 % at 5° of roll.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from sideslip_sim.vehicle import GRAVITY_MPS2

FRAMES = ("level", "body")
"""``level``: the CG acceleration in the horizontal vehicle frame (gravity-free, the
contract's and every shipped model's); ``body``: specific force in the body frame."""

MAX_OFFSET_M = 5.0
"""Larger lever arms are refused: no IMU sits 5 m from a passenger car's CG."""


class ImuMountingError(ValueError):
    """An IMU mounting that names an unknown frame or an implausible position."""


@dataclass(frozen=True)
class ImuMounting:
    """Where the IMU is and which frame its accelerometer reports in.

    position_m: (x, y) of the IMU from the whole-vehicle CG, body frame, x forward, y
        left [m].
    frame: ``level`` (default: gravity-free, horizontal frame, what the simulator has
        always published) or ``body`` (specific force in the body frame, gravity's
        projection through roll and pitch included).
    """

    position_m: tuple[float, float] = (0.0, 0.0)
    frame: str = "level"

    def __post_init__(self) -> None:
        if self.frame not in FRAMES:
            raise ImuMountingError(f"IMU frame {self.frame!r}: must be one of {', '.join(FRAMES)}")
        if len(self.position_m) != 2:
            raise ImuMountingError(f"IMU position {self.position_m!r}: give [x, y] in metres")
        for axis, value in zip("xy", self.position_m, strict=True):
            if not math.isfinite(value) or abs(value) > MAX_OFFSET_M:
                raise ImuMountingError(
                    f"IMU position {axis} = {value!r} m: must be finite and within "
                    f"±{MAX_OFFSET_M:g} m of the CG"
                )

    @property
    def ideal(self) -> bool:
        """At the CG and gravity-free: the samples are the simulator's own."""
        return self.frame == "level" and self.position_m == (0.0, 0.0)

    def to_dict(self) -> dict[str, object]:
        """The bag-metadata record (``run_metadata``'s ``imu``)."""
        return {"position_m": list(self.position_m), "frame": self.frame}

    @classmethod
    def from_mapping(cls, data: Mapping[str, object]) -> ImuMounting:
        """Read :meth:`to_dict`'s record (or a user's YAML with the same keys)."""
        unknown = set(data) - {"position_m", "frame"}
        if unknown:
            raise ImuMountingError(f"IMU mounting: unknown key(s) {', '.join(sorted(unknown))}")
        raw = data.get("position_m", (0.0, 0.0))
        if not isinstance(raw, list | tuple):
            raise ImuMountingError(f"IMU position {raw!r}: give [x, y] in metres")
        try:
            position = tuple(float(v) for v in raw)
        except (TypeError, ValueError):
            raise ImuMountingError(f"IMU position {raw!r}: give [x, y] in metres") from None
        return cls(position, str(data.get("frame", "level")))  # type: ignore[arg-type]


def mounted_accelerations(
    mounting: ImuMounting,
    t_s: np.ndarray,
    ax_mps2: np.ndarray,
    ay_mps2: np.ndarray,
    yaw_rate_radps: np.ndarray,
    roll_rad: np.ndarray,
    pitch_rad: np.ndarray,
    gravity_x_mps2: np.ndarray | float = 0.0,
    gravity_y_mps2: np.ndarray | float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """What an IMU mounted as ``mounting`` reads, from the CG accelerations in the
    horizontal frame [m/s²], the yaw rate [rad/s], the body's roll and pitch [rad] and
    gravity's share in the road plane [m/s²] (a banked road's) on the time base ``t_s``
    [s] (see module)."""
    x, y = mounting.position_m
    ax, ay = np.asarray(ax_mps2, dtype=float), np.asarray(ay_mps2, dtype=float)
    if x or y:
        r = np.asarray(yaw_rate_radps, dtype=float)
        r_dot = np.gradient(r, t_s) if r.size > 1 else np.zeros_like(r)
        ax = ax - r_dot * y - r**2 * x
        ay = ay + r_dot * x - r**2 * y
    if mounting.frame == "body":
        phi, theta = np.asarray(roll_rad, dtype=float), np.asarray(pitch_rad, dtype=float)
        ax = (ax - gravity_x_mps2) * np.cos(theta) - GRAVITY_MPS2 * np.sin(theta)
        ay = (ay - gravity_y_mps2) * np.cos(phi) + GRAVITY_MPS2 * np.sin(phi)
    return ax, ay
