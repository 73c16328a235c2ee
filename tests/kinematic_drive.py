"""A drive whose Y_a obeys the plane kinematics exactly, a_y = v̇_y + v_x·ψ̇, read by an
accelerometer with a known scale and bias: what the Y_a scale fits must give back.

Not a vehicle model (the simulator's drives are for that): broadband steering (eight
sines of 0.02–0.6 Hz, random phases) and a lateral velocity that follows the turn, so
the fit can tell the scale from the lateral velocity, at any rate and length.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

START_NS = 1_000_000_000_000

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class KinematicDrive:
    """Stamps [ns], X_v [m/s], ψ̇ [rad/s], Y_a [m/s²] as recorded (noisy), and a_y
    [m/s²], the lateral acceleration the recorded Y_a is ``scale``·a_y + ``bias`` of."""

    stamp_ns: npt.NDArray[np.int64]
    x_v_mps: FloatArray
    yaw_rate_radps: FloatArray
    y_a_mps2: FloatArray
    a_y_mps2: FloatArray

    def samples(self) -> list[tuple[int, float, float, float]]:
        """(stamp, X_v, ψ̇, Y_a) per sample, as :meth:`add` takes them."""
        return list(
            zip(
                self.stamp_ns.tolist(),
                self.x_v_mps.tolist(),
                self.yaw_rate_radps.tolist(),
                self.y_a_mps2.tolist(),
                strict=True,
            )
        )


def kinematic_drive(
    seconds: float,
    *,
    scale: float = 1.0,
    bias: float = 0.0,
    seed: int = 0,
    rate_hz: float = 400.0,
    start_ns: int = START_NS,
) -> KinematicDrive:
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * rate_hz)) / rate_hz
    u = 18.0 + 4.0 * np.sin(2 * np.pi * t / 47.0 + rng.uniform(0, 6))
    freqs, phases = rng.uniform(0.02, 0.6, 8), rng.uniform(0, 2 * np.pi, 8)
    sines = (np.sin(2 * np.pi * f * t + p) for f, p in zip(freqs, phases, strict=True))
    r = 0.01 + 0.028 * sum(sines)
    v_y = -0.04 * u * r
    a_y = np.gradient(v_y, t) + u * r
    return KinematicDrive(
        stamp_ns=(start_ns + np.round(t * 1e9)).astype(np.int64),
        x_v_mps=u + rng.normal(0, 0.05, t.size),
        yaw_rate_radps=r + rng.normal(0, 0.002, t.size),
        y_a_mps2=scale * a_y + bias + rng.normal(0, 0.05, t.size),
        a_y_mps2=a_y,
    )
