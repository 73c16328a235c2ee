"""Polynomial atan, sin, cos and exp for the numba tyre kernels, inlined into their callers.

Why not libm: :func:`~sideslip_sim.tire_forces.combined_forces` needs up to eight atan,
four sin/cos and one exp per call; with libm it took ~180 ns (16 calls per 2.5-ms step at
1000x real time leave 2.5 µs for everything), with these ~105 ns. A libm call also forces
every live value to be spilled around it, and keeps LLVM from vectorising
:func:`~sideslip_sim.tire_forces.combined_forces4`.

Polynomials: our own least-squares fits on Chebyshev nodes (numpy against mpmath); error
vs libm ~1e-15 (exp: relative error < 1e-12), checked in tests. Odd/even symmetry is exact
because the kernels work on |x| and restore the sign. All angles in radians.

Every function here is decorated with :data:`inline_njit`, so it exists only inside the
``@njit`` function that calls it; call them from compiled code.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["inline_njit", "poly_atan", "poly_cos", "poly_exp", "poly_sin"]

# Numpy error model (a zero divisor gives inf/nan, never raises inside an integrator) and
# numba's default FMA contraction (faster and at least as accurate; sign symmetric), as for
# every tyre kernel. inline="always": inlined at numba-IR level, so each public kernel that
# uses these helpers compiles to one function.
inline_njit = njit(cache=True, error_model="numpy", inline="always")

_TAN_PI_8 = 0.41421356237309503
_TAN_3PI_8 = 2.414213562373095
_HALF_PI = 0.5 * math.pi


@inline_njit
def poly_atan(x: float) -> float:
    """atan(x) [rad]: reduce to |u| ≤ tan(π/8), then u·P(u²) with P of degree 9."""
    ax = abs(x)
    # Written as selects, not branches: slip arguments jump around, mispredicts cost more
    # than the always-executed division.
    big = ax > _TAN_3PI_8
    mid = ax > _TAN_PI_8
    num = -1.0 if big else (ax - 1.0 if mid else ax)
    den = ax if big else (ax + 1.0 if mid else 1.0)
    offset = _HALF_PI if big else (0.25 * math.pi if mid else 0.0)
    u = num / den
    # Estrin's scheme (not Horner): a shorter dependency chain, this code is latency bound.
    z = u * u
    z2 = z * z
    z4 = z2 * z2
    p = (
        (0.9999999999999989 - 0.3333333333322525 * z)
        + (0.19999999978972652 - 0.14285712695696334 * z) * z2
        + (
            (0.11111049861532936 - 0.09089546851603536 * z)
            + (0.07673702619613414 - 0.06506950296698395 * z) * z2
        )
        * z4
        + (0.05027786465051508 - 0.02535593200016057 * z) * (z4 * z4)
    )
    r = offset + u * p
    return r if x >= 0.0 else -r


@inline_njit
def _sin_kernel(x: float) -> float:
    """sin(x) for |x| ≤ π/2 [rad]: x·P(x²) with P of degree 7."""
    z = x * x
    z2 = z * z
    p = (
        (0.9999999999999998 - 0.16666666666666055 * z)
        + (0.008333333333280318 - 0.00019841269824204125 * z) * z2
        + (
            (2.755731652777335e-06 - 2.5051876827946792e-08 * z)
            + (1.604801017283525e-10 - 7.372489024677799e-13 * z) * z2
        )
        * (z2 * z2)
    )
    return x * p


@inline_njit
def poly_sin(theta: float) -> float:
    """sin(θ) for |θ| ≤ π [rad] (all a Magic Formula shape factor C ≤ 2 can produce)."""
    a = abs(theta)
    s = _sin_kernel(math.pi - a if a > _HALF_PI else a)
    return s if theta >= 0.0 else -s


@inline_njit
def poly_cos(theta: float) -> float:
    """cos(θ) for |θ| ≤ π [rad]."""
    a = abs(theta)
    return _sin_kernel(_HALF_PI - a)


@inline_njit
def poly_exp(x: float) -> float:
    """exp(x) for |x| ≤ 16 (x clipped there; rel. error < 1e-12).

    Taylor series for exp(x/64), then squared 6 times.
    """
    r = min(max(x, -16.0), 16.0) * 0.015625
    r2 = r * r
    r4 = r2 * r2
    p = (
        (1.0 + r)
        + (0.5 + r * (1.0 / 6.0)) * r2
        + ((1.0 / 24.0 + r * (1.0 / 120.0)) + (1.0 / 720.0 + r * (1.0 / 5040.0)) * r2) * r4
        + ((1.0 / 40320.0 + r * (1.0 / 362880.0)) + (1.0 / 3628800.0) * r2) * (r4 * r4)
    )
    for _ in range(6):
        p = p * p
    return p
