"""Steady-state tyre forces: Pacejka Magic Formula 5.2, pure and combined slip, camber 0.

Equations: MF 5.2 as in H. B. Pacejka, "Tyre and Vehicle Dynamics", 2nd ed. (2006), §4.3
(the form used by MF-Tyre 5.2 / PAC2002 ``.tir`` files), with load sensitivity through
dfz = (Fz − Fz0')/Fz0', Fz0' = FNOMIN·LFZO, and combined slip through the weighting
functions Gxα (RBX1, RBX2, RCX1, REX1, REX2) and Gyκ (RBY1, RBY2, RCY1, REY1, REY2).

Frame and sign convention (wheel frame, ISO 8855 axes: x forward along the wheel heading,
y to the left, z up; V_cx, V_cy = contact-point velocity in that frame)::

    kappa     = (ω·R_e − V_cx) / |V_cx|    > 0 driving, < 0 braking       [-]
    tan_alpha = −V_cy / |V_cx|              > 0 when the contact patch slides to the right
    fx_n > 0 for kappa > 0 (pushes forward), fy_n > 0 for tan_alpha > 0 (pushes left)

so the cornering stiffness is positive. ``.tir`` files in the TYDEX/ISO sign set have
PDY1 < 0 and PKY1 < 0 (Fy = −C_α·α); the model uses the magnitudes of the friction and
stiffness coefficients (PDY1/PDY2 and PKX1/PKX2 flip together, keeping their ratio), so
both sign sets give the same forces here.

Deliberate departures from the full MF 5.2 (all such terms are still parsed and packed):

* Symmetry. SHx, SVx, SHy, SVy, SVyκ (RVY*), SHxα (RHX1), SHyκ (RHY*), RBY3, and the
  sign(κ)/sign(α) curvature terms PEX4 and PEY3 are dropped. They encode a measured tyre's
  ply-steer/conicity asymmetry; sideslip's vehicle model mounts the same tyre on both
  sides without mirroring it, so these terms would make a car pull on a straight road and
  break the test that a mirrored manoeuvre gives a mirrored response. Without them fx is
  odd in kappa and even in tan_alpha, fy odd in tan_alpha and even in kappa, and both are
  zero at zero slip.
* Friction. ``mu_scale`` (road μ relative to the test surface) is applied by similarity:
  F(κ, tanα; μs) = μs·F(κ/μs, tanα/μs; 1). Peak forces scale with μs, the slip at the
  peak scales with μs, the slip stiffnesses at zero slip are unchanged.
* Load range. Beyond Fz = 4·Fz0' the load-dependent shape (μ, E, K) is frozen and forces
  grow in proportion to Fz, so the dfz polynomials can never flip the sign of μ at
  absurd loads. μ is floored at 0; E ≤ 1 and Gxα, Gyκ ≥ 0 as MF-Tyre requires.
* Camber is 0: PDY3, PKY3, PEY4, PVY3/4, RVY3 and the camber scaling factors are unused.

Numba: every ``@njit`` function takes the packed array ``coef`` from
:meth:`TireParams.coefficients`; index it with the ``I_<KEY>`` constants.
:func:`combined_forces4` computes the four corners of a car in one call, vectorised
(AVX2: one lane per corner); it gives the same forces as four :func:`combined_forces` calls.
The scalar function is the readable reference of the equations; the vehicle model calls
the vectorised one (about 3× faster), and a property test holds the two equal, so an edit
to one must be made to both.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from sideslip_sim.tir import TirError, TirFile, parse_tir

__all__ = [
    "COEFFICIENT_KEYS",
    "DEFAULT_TIR",
    "SIGMA_MIN_M",
    "TireParams",
    "combined_forces",
    "combined_forces4",
    "cornering_stiffness",
    "friction_coefficients",
    "load_tire",
    "longitudinal_stiffness",
    "relaxation_lengths",
    "rolling_resistance_coefficient",
]

DEFAULT_TIR = Path(__file__).resolve().parent / "data" / "tires" / "pacejka2006_205_60R15.tir"

# Order of the packed coefficient array: (section, keys). The I_* constants below index it;
# tests check that they agree with this table.
_LAYOUT: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("VERTICAL", ("FNOMIN", "VERTICAL_STIFFNESS", "VERTICAL_DAMPING")),
    ("DIMENSION", ("UNLOADED_RADIUS",)),
    (
        "SCALING_COEFFICIENTS",
        (
            "LFZO", "LCX", "LMUX", "LEX", "LKX", "LHX", "LVX", "LCY", "LMUY", "LEY", "LKY",
            "LHY", "LVY", "LXAL", "LYKA", "LVYKA", "LSGKP", "LSGAL", "LMY",
        ),
    ),
    (
        "LONGITUDINAL_COEFFICIENTS",
        (
            "PCX1", "PDX1", "PDX2", "PEX1", "PEX2", "PEX3", "PEX4", "PKX1", "PKX2", "PKX3",
            "PHX1", "PHX2", "PVX1", "PVX2", "RBX1", "RBX2", "RCX1", "REX1", "REX2", "RHX1",
            "PTX1", "PTX2", "PTX3",
        ),
    ),
    (
        "LATERAL_COEFFICIENTS",
        (
            "PCY1", "PDY1", "PDY2", "PEY1", "PEY2", "PEY3", "PKY1", "PKY2", "PHY1", "PHY2",
            "PVY1", "PVY2", "RBY1", "RBY2", "RBY3", "RCY1", "REY1", "REY2", "RHY1", "RHY2",
            "RVY1", "RVY2", "RVY4", "RVY5", "RVY6", "PTY1", "PTY2",
        ),
    ),
    ("ROLLING_COEFFICIENTS", ("QSY1", "QSY2")),
)  # fmt: skip
COEFFICIENT_KEYS: tuple[str, ...] = tuple(key for _, keys in _LAYOUT for key in keys)
_SECTION_OF: dict[str, str] = {key: section for section, keys in _LAYOUT for key in keys}

# [VERTICAL], [DIMENSION]
I_FNOMIN = 0
I_VERTICAL_STIFFNESS = 1
I_VERTICAL_DAMPING = 2
I_UNLOADED_RADIUS = 3
# [SCALING_COEFFICIENTS]
I_LFZO = 4
I_LCX = 5
I_LMUX = 6
I_LEX = 7
I_LKX = 8
I_LHX = 9
I_LVX = 10
I_LCY = 11
I_LMUY = 12
I_LEY = 13
I_LKY = 14
I_LHY = 15
I_LVY = 16
I_LXAL = 17
I_LYKA = 18
I_LVYKA = 19
I_LSGKP = 20
I_LSGAL = 21
I_LMY = 22
# [LONGITUDINAL_COEFFICIENTS]
I_PCX1 = 23
I_PDX1 = 24
I_PDX2 = 25
I_PEX1 = 26
I_PEX2 = 27
I_PEX3 = 28
I_PEX4 = 29
I_PKX1 = 30
I_PKX2 = 31
I_PKX3 = 32
I_PHX1 = 33
I_PHX2 = 34
I_PVX1 = 35
I_PVX2 = 36
I_RBX1 = 37
I_RBX2 = 38
I_RCX1 = 39
I_REX1 = 40
I_REX2 = 41
I_RHX1 = 42
I_PTX1 = 43
I_PTX2 = 44
I_PTX3 = 45
# [LATERAL_COEFFICIENTS]
I_PCY1 = 46
I_PDY1 = 47
I_PDY2 = 48
I_PEY1 = 49
I_PEY2 = 50
I_PEY3 = 51
I_PKY1 = 52
I_PKY2 = 53
I_PHY1 = 54
I_PHY2 = 55
I_PVY1 = 56
I_PVY2 = 57
I_RBY1 = 58
I_RBY2 = 59
I_RBY3 = 60
I_RCY1 = 61
I_REY1 = 62
I_REY2 = 63
I_RHY1 = 64
I_RHY2 = 65
I_RVY1 = 66
I_RVY2 = 67
I_RVY4 = 68
I_RVY5 = 69
I_RVY6 = 70
I_PTY1 = 71
I_PTY2 = 72
# [ROLLING_COEFFICIENTS]
I_QSY1 = 73
I_QSY2 = 74
N_COEFFICIENTS = 75

# Value ranges beyond "finite". Positive: they divide or set the load scale. Shape factors
# C ≤ 2: a larger C makes the force change sign at large slip (and the sin/cos kernels
# below assume |C·atan| ≤ π). |PKX3|, |PTX3| ≤ 5 keeps exp(±P·dfz) inside _exp's range.
_POSITIVE = ("FNOMIN", "UNLOADED_RADIUS", "VERTICAL_STIFFNESS", "LFZO", "PKY2", "PTY2")
_SHAPE_FACTORS = ("PCX1", "PCY1", "RCX1", "RCY1")
_EXPONENTS = ("PKX3", "PTX3")
# Accepted spellings in [UNITS]; sideslip works in SI only.
_SI_UNITS = {
    "LENGTH": {"meter", "metre", "m"},
    "FORCE": {"newton", "n"},
    "ANGLE": {"radian", "radians", "rad"},
    "MASS": {"kg", "kilogram"},
    "TIME": {"second", "s", "sec"},
}

# All numerical kernels: numpy error model (a zero divisor gives inf/nan, never raises inside
# an integrator) and FMA contraction (faster and at least as accurate; sign symmetric).
_kernel = njit(cache=True, error_model="numpy")
# Private helpers are inlined at numba-IR level, so each public kernel is one function.
_inline = njit(cache=True, error_model="numpy", inline="always")

SIGMA_MIN_M = 0.05  # floor of the relaxation lengths; also what a lifted wheel gets [m]
_DFZ_MAX = 3.0  # load dependence frozen beyond Fz = (1 + _DFZ_MAX)·Fz0'
_SLIP_ARG_MAX = 1.0e6  # |B·slip| clip: atan is flat there, and it keeps inf out of E-terms
_EPS = 1.0e-9  # keeps B = K/(C·D) finite when D = 0 (μ floored, or zero friction)


@dataclass(frozen=True)
class TireParams:
    """MF 5.2 coefficients of one tyre, in :data:`COEFFICIENT_KEYS` order (SI units).

    Build with :meth:`from_tir`; read a value with ``params["PKY1"]``.
    """

    source: str
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.values) != N_COEFFICIENTS:
            raise ValueError(f"{self.source}: expected {N_COEFFICIENTS} coefficients")
        for key, value in zip(COEFFICIENT_KEYS, self.values, strict=True):
            problem = _range_problem(key, value)
            if problem:
                raise ValueError(f"{self.source}: {key} = {value} {problem}")

    @classmethod
    def from_tir(cls, path: str | Path = DEFAULT_TIR) -> TireParams:
        """Read a ``.tir`` file; :class:`TirError` names the file and key on any problem."""
        return cls.from_tir_file(parse_tir(path))

    @classmethod
    def from_tir_file(cls, tir: TirFile) -> TireParams:
        """Pick the keys this model needs out of a parsed file and check them."""
        _check_units(tir)
        values = []
        for key in COEFFICIENT_KEYS:
            section = _SECTION_OF[key]
            value = tir.number(section, key)
            problem = _range_problem(key, value)
            if problem:
                raise TirError(
                    tir.path,
                    f"[{section}] {key} = {value} {problem}",
                    line=tir.lines.get((section, key)),
                    section=section,
                    key=key,
                )
            values.append(value)
        return cls(source=tir.path, values=tuple(values))

    def __getitem__(self, key: str) -> float:
        return self.values[COEFFICIENT_KEYS.index(key)]

    def with_values(self, **overrides: float) -> TireParams:
        """A copy with some coefficients replaced, e.g. ``with_values(LMUY=0.8)``."""
        unknown = sorted(set(overrides) - set(COEFFICIENT_KEYS))
        if unknown:
            raise KeyError(f"unknown tyre coefficient(s): {', '.join(unknown)}")
        values = tuple(
            float(overrides.get(k, v)) for k, v in zip(COEFFICIENT_KEYS, self.values, strict=True)
        )
        return TireParams(source=f"{self.source} (modified)", values=values)

    def coefficients(self) -> np.ndarray:
        """A fresh float64 array for the ``@njit`` functions; index with ``I_<KEY>``."""
        return np.array(self.values, dtype=np.float64)

    @property
    def fnomin_n(self) -> float:
        """Nominal wheel load FNOMIN [N]."""
        return self.values[I_FNOMIN]

    @property
    def unloaded_radius_m(self) -> float:
        """Free tyre radius R0 [m]."""
        return self.values[I_UNLOADED_RADIUS]

    @property
    def vertical_stiffness_n_per_m(self) -> float:
        return self.values[I_VERTICAL_STIFFNESS]

    @property
    def vertical_damping_ns_per_m(self) -> float:
        return self.values[I_VERTICAL_DAMPING]


def _range_problem(key: str, value: float) -> str | None:
    """What is wrong with this coefficient value, or None."""
    if not math.isfinite(value):
        return "must be a finite number"
    if key in _POSITIVE and not value > 0.0:
        return "must be > 0"
    if key in _SHAPE_FACTORS and not 0.0 < value <= 2.0:
        return "must be in (0, 2]"
    if key in _EXPONENTS and not -5.0 <= value <= 5.0:
        return "must be in [-5, 5]"
    return None


def _check_units(tir: TirFile) -> None:
    for key, accepted in _SI_UNITS.items():
        if not tir.has("UNITS", key):
            continue
        unit = tir.string("UNITS", key)
        if unit.strip().lower() not in accepted:
            raise TirError(
                tir.path,
                f"[UNITS] {key} = {unit!r} not supported (sideslip reads SI files only)",
                line=tir.lines.get(("UNITS", key)),
                section="UNITS",
                key=key,
            )


# --------------------------------------------------------------------------- numba core


@_inline
def _load_state(fnomin, lfzo, fz_n):
    """(Fz0', dfz frozen at _DFZ_MAX, load actually used for the shape, ratio Fz/that)."""
    fz0 = fnomin * lfzo
    fz_shape = min(fz_n, (1.0 + _DFZ_MAX) * fz0)
    return fz0, fz_shape / fz0 - 1.0, fz_shape, fz_n / fz_shape


# Inline kernels for atan, sin, cos, exp. combined_forces needs up to eight atan, four sin/cos
# and one exp per call; with libm it took ~180 ns (16 calls per 2.5-ms step at 1000x real
# time leave 2.5 µs for everything), with these ~105 ns. Polynomials: our own least-squares
# fits on Chebyshev nodes (numpy against mpmath); error vs libm ~1e-15, checked in tests.
# Odd/even symmetry is exact because the kernels work on |x| and restore the sign.
_TAN_PI_8 = 0.41421356237309503
_TAN_3PI_8 = 2.414213562373095
_HALF_PI = 0.5 * math.pi


@_inline
def _atan(x):
    """atan(x): reduce to |u| ≤ tan(π/8), then u·P(u²) with P of degree 9."""
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


@_inline
def _sin_kernel(x):
    """sin(x) for |x| ≤ π/2: x·P(x²) with P of degree 7."""
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


@_inline
def _sin(theta):
    """sin(θ) for |θ| ≤ π (all a shape factor C ≤ 2 can produce)."""
    a = abs(theta)
    s = _sin_kernel(math.pi - a if a > _HALF_PI else a)
    return s if theta >= 0.0 else -s


@_inline
def _cos(theta):
    """cos(θ) for |θ| ≤ π."""
    a = abs(theta)
    return _sin_kernel(_HALF_PI - a)


@_inline
def _exp(x):
    """exp(x) for |x| ≤ 16 (rel. error < 1e-12): Taylor for exp(x/64), then squared 6 times.

    Inline instead of libm: a call forces every live value to be spilled around it.
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


@_inline
def _mf_angle(x, c, e):
    """The Magic Formula's angle C·atan(x − E·(x − atan x)) for x = B·slip (x clipped)."""
    x = min(max(x, -_SLIP_ARG_MAX), _SLIP_ARG_MAX)
    if e != 0.0:
        x = x - e * (x - _atan(x))
    return c * _atan(x)


@_inline
def _sign(value):
    return -1.0 if value < 0.0 else 1.0


@_inline
def _kx(pkx1, pkx2, pkx3, lkx, fz_shape, dfz):
    """Longitudinal slip stiffness at the shape load [N per unit slip], ≥ 0."""
    k = fz_shape * _sign(pkx1) * (pkx1 + pkx2 * dfz) * _exp(pkx3 * dfz)
    return max(k * lkx, 0.0)


@_inline
def _ky(pky1, pky2, lky, fz0, fz_shape):
    """Cornering stiffness at the shape load [N/rad]; sin(2·atan u) = 2u/(1 + u²)."""
    u = fz_shape / (pky2 * fz0)
    return abs(pky1) * fz0 * (2.0 * u / (1.0 + u * u)) * lky


@_inline
def _mu(pd1, pd2, lmu, dfz):
    """Peak friction at the shape load, sign-normalised (ISO files have PDY1 < 0), ≥ 0."""
    return max(_sign(pd1) * (pd1 + pd2 * dfz) * lmu, 0.0)


@_kernel
def combined_forces(coef, fz_n, kappa, tan_alpha, mu_scale):
    """Steady-state (fx_n, fy_n) [N] of one tyre, MF 5.2 combined slip, camber 0.

    coef: :meth:`TireParams.coefficients`; fz_n: wheel load [N] (≤ 0 means lifted →
    exactly (0, 0)); kappa = (ω·R_e − V_cx)/|V_cx| [-]; tan_alpha = −V_cy/|V_cx| [-];
    mu_scale: road friction relative to the tyre's test surface (1.0 = as tested, ≤ 0 →
    (0, 0)). Wheel frame, x forward, y left: fx > 0 for kappa > 0, fy > 0 for
    tan_alpha > 0. Symmetric by construction (fx odd in kappa, fy odd in tan_alpha; the
    asymmetric shift terms are dropped, see the module docstring for why). Finite for any
    finite input; NaN in gives NaN out.
    """
    # All array reads come first, before any branch: numba then drops the array's
    # reference counting (an atomic increment and decrement per call otherwise).
    fz0, dfz, fz_shape, load_ratio = _load_state(coef[I_FNOMIN], coef[I_LFZO], fz_n)
    k_x = _kx(coef[I_PKX1], coef[I_PKX2], coef[I_PKX3], coef[I_LKX], fz_shape, dfz)
    pdx1, pdx2, lmux = coef[I_PDX1], coef[I_PDX2], coef[I_LMUX]
    pdy1, pdy2, lmuy = coef[I_PDY1], coef[I_PDY2], coef[I_LMUY]
    c_x = coef[I_PCX1] * coef[I_LCX]
    pex1, pex2, pex3, lex = coef[I_PEX1], coef[I_PEX2], coef[I_PEX3], coef[I_LEX]
    c_y = coef[I_PCY1] * coef[I_LCY]
    pey1, pey2, ley = coef[I_PEY1], coef[I_PEY2], coef[I_LEY]
    pky1, pky2, lky = coef[I_PKY1], coef[I_PKY2], coef[I_LKY]
    rbx1, rbx2, rcx1 = coef[I_RBX1] * coef[I_LXAL], coef[I_RBX2], coef[I_RCX1]
    rex1, rex2 = coef[I_REX1], coef[I_REX2]
    rby1, rby2, rcy1 = coef[I_RBY1] * coef[I_LYKA], coef[I_RBY2], coef[I_RCY1]
    rey1, rey2 = coef[I_REY1], coef[I_REY2]

    if fz_n <= 0.0 or mu_scale <= 0.0:
        return 0.0, 0.0
    kappa = kappa / mu_scale  # similarity: same curve, slip axis scaled with μ
    tan_alpha = tan_alpha / mu_scale

    # Pure longitudinal slip.
    d_x = _mu(pdx1, pdx2, lmux, dfz) * fz_shape
    e_x = min((pex1 + (pex2 + pex3 * dfz) * dfz) * lex, 1.0)
    b_x = k_x / (c_x * d_x + _EPS)
    fx0 = d_x * _sin(_mf_angle(b_x * kappa, c_x, e_x))

    # Pure lateral slip (α* = tan α, as in MF 5.2).
    d_y = _mu(pdy1, pdy2, lmuy, dfz) * fz_shape
    e_y = min((pey1 + pey2 * dfz) * ley, 1.0)
    b_y = _ky(pky1, pky2, lky, fz0, fz_shape) / (c_y * d_y + _EPS)
    fy0 = d_y * _sin(_mf_angle(b_y * tan_alpha, c_y, e_y))

    # Combined-slip weights Gxα, Gyκ; cos(atan z) = 1/sqrt(1 + z²).
    r = rbx2 * kappa
    b_xa = rbx1 / math.sqrt(1.0 + r * r)
    g_xa = max(_cos(_mf_angle(b_xa * tan_alpha, rcx1, min(rex1 + rex2 * dfz, 1.0))), 0.0)
    r = rby2 * tan_alpha
    b_yk = rby1 / math.sqrt(1.0 + r * r)
    g_yk = max(_cos(_mf_angle(b_yk * kappa, rcy1, min(rey1 + rey2 * dfz, 1.0))), 0.0)

    scale = mu_scale * load_ratio
    return scale * g_xa * fx0, scale * g_yk * fy0


# ------------------------------------------------------------- four corners at once
#
# combined_forces4 is the same model, written for LLVM's loop vectoriser: one SIMD lane per
# corner, no branches that depend on a lane (clips are min/max, special cases selects), no
# libm calls. What it takes to get the loop vectorised (check: inspect_asm shows ymm):
# * Numba leaves LLVM's SLP vectoriser off (NUMBA_SLP_VECTORIZE=0), so four copies of
#   straight-line code stay scalar; it has to be a `for i in range(4)` loop.
# * A loop of known trip count 4 is vectorised only if it needs no run-time alias checks,
#   and the caller's arrays may overlap. So the loop reads and writes only a private
#   stack buffer (_scratch): inputs are copied in before it, results copied out after.
# * The E-term of _mf_angle is always evaluated (x − 0·(x − atan x) is exactly x, so this
#   changes no result), except that a tyre whose combined-slip curvatures REX*, REY* are all
#   zero (most files) gets a second copy of the loop without those two atan.

_SCRATCH_SIZE = 20  # [0:4] fx, [4:8] fy, [8:12] fz, [12:16] kappa, [16:20] tan_alpha


@intrinsic
def _scratch(typingctx):
    """A float64 buffer of _SCRATCH_SIZE on the stack (entry-block alloca), as a pointer."""

    def codegen(context, builder, signature, args):
        return cgutils.alloca_once(
            builder, context.get_value_type(types.float64), size=_SCRATCH_SIZE
        )

    return types.CPointer(types.float64)(), codegen


@_inline
def _mf_angle_lane(x, c, e, use_e):
    """_mf_angle without a lane-dependent branch; use_e=False (a constant) drops the E-term."""
    x = min(max(x, -_SLIP_ARG_MAX), _SLIP_ARG_MAX)
    if use_e:
        x = x - e * (x - _atan(x))
    return c * _atan(x)


@_inline
def _forces_lanes(coef, buf, mu_scale, combined_e):
    """combined_forces for the four corners in buf[8:20] → buf[0:8]; mu_scale > 0 or NaN."""
    fnomin, lfzo = coef[I_FNOMIN], coef[I_LFZO]
    pkx1, pkx2, pkx3, lkx = coef[I_PKX1], coef[I_PKX2], coef[I_PKX3], coef[I_LKX]
    pdx1, pdx2, lmux = coef[I_PDX1], coef[I_PDX2], coef[I_LMUX]
    pdy1, pdy2, lmuy = coef[I_PDY1], coef[I_PDY2], coef[I_LMUY]
    c_x = coef[I_PCX1] * coef[I_LCX]
    pex1, pex2, pex3, lex = coef[I_PEX1], coef[I_PEX2], coef[I_PEX3], coef[I_LEX]
    c_y = coef[I_PCY1] * coef[I_LCY]
    pey1, pey2, ley = coef[I_PEY1], coef[I_PEY2], coef[I_LEY]
    pky1, pky2, lky = coef[I_PKY1], coef[I_PKY2], coef[I_LKY]
    rbx1, rbx2, rcx1 = coef[I_RBX1] * coef[I_LXAL], coef[I_RBX2], coef[I_RCX1]
    rex1, rex2 = coef[I_REX1], coef[I_REX2]
    rby1, rby2, rcy1 = coef[I_RBY1] * coef[I_LYKA], coef[I_RBY2], coef[I_RCY1]
    rey1, rey2 = coef[I_REY1], coef[I_REY2]
    fz_lifted = fnomin * lfzo  # any positive load: a lifted lane computes, then gets 0

    for i in range(4):
        fz_n = buf[8 + i]
        lifted = fz_n <= 0.0  # False for NaN: NaN goes through, as in combined_forces
        fz_n = fz_lifted if lifted else fz_n
        fz0, dfz, fz_shape, load_ratio = _load_state(fnomin, lfzo, fz_n)
        k_x = _kx(pkx1, pkx2, pkx3, lkx, fz_shape, dfz)
        kappa = buf[12 + i] / mu_scale
        tan_alpha = buf[16 + i] / mu_scale

        # From here on the same expressions as combined_forces, in the same order.
        d_x = _mu(pdx1, pdx2, lmux, dfz) * fz_shape
        e_x = min((pex1 + (pex2 + pex3 * dfz) * dfz) * lex, 1.0)
        b_x = k_x / (c_x * d_x + _EPS)
        fx0 = d_x * _sin(_mf_angle_lane(b_x * kappa, c_x, e_x, True))

        d_y = _mu(pdy1, pdy2, lmuy, dfz) * fz_shape
        e_y = min((pey1 + pey2 * dfz) * ley, 1.0)
        b_y = _ky(pky1, pky2, lky, fz0, fz_shape) / (c_y * d_y + _EPS)
        fy0 = d_y * _sin(_mf_angle_lane(b_y * tan_alpha, c_y, e_y, True))

        r = rbx2 * kappa
        b_xa = rbx1 / math.sqrt(1.0 + r * r)
        e_xa = min(rex1 + rex2 * dfz, 1.0)
        g_xa = max(_cos(_mf_angle_lane(b_xa * tan_alpha, rcx1, e_xa, combined_e)), 0.0)
        r = rby2 * tan_alpha
        b_yk = rby1 / math.sqrt(1.0 + r * r)
        e_yk = min(rey1 + rey2 * dfz, 1.0)
        g_yk = max(_cos(_mf_angle_lane(b_yk * kappa, rcy1, e_yk, combined_e)), 0.0)

        scale = mu_scale * load_ratio
        fx = scale * g_xa * fx0
        fy = scale * g_yk * fy0
        buf[i] = 0.0 if lifted else fx
        buf[4 + i] = 0.0 if lifted else fy


@_kernel
def combined_forces4(coef, fz_n, kappa, tan_alpha, mu_scale, fx_out, fy_out):
    """:func:`combined_forces` for four tyres at once, SIMD-vectorised over the four.

    fz_n, kappa, tan_alpha: float64 arrays of length 4 (one entry per corner; any layout,
    they are read before anything is written, so they may share memory with the outputs);
    mu_scale: one road friction scale for all four. Writes fx_out[i], fy_out[i] [N] (float64
    arrays of length ≥ 4). Same results as four combined_forces calls, to rounding
    (the operations are the same; FMA contraction may differ by an ulp between the scalar
    and the vector code), same special cases: fz ≤ 0 or mu_scale ≤ 0 → exactly 0, NaN in →
    NaN out.
    """
    combined_e = (
        coef[I_REX1] != 0.0 or coef[I_REX2] != 0.0 or coef[I_REY1] != 0.0 or coef[I_REY2] != 0.0
    )
    if mu_scale <= 0.0:
        for i in range(4):
            fx_out[i] = 0.0
            fy_out[i] = 0.0
        return
    buf = _scratch()
    for i in range(4):
        buf[8 + i] = fz_n[i]
        buf[12 + i] = kappa[i]
        buf[16 + i] = tan_alpha[i]
    # Two copies of the loop; the flag is a constant inside each, so LLVM drops the dead
    # E-term code from the second.
    if combined_e:
        _forces_lanes(coef, buf, mu_scale, True)
    else:
        _forces_lanes(coef, buf, mu_scale, False)
    for i in range(4):
        fx_out[i] = buf[i]
        fy_out[i] = buf[4 + i]


@_kernel
def friction_coefficients(coef, fz_n):
    """Peak (μx, μy) of the pure-slip curves at load fz_n on the test surface [-]."""
    if fz_n <= 0.0:
        return 0.0, 0.0
    _, dfz, _, _ = _load_state(coef[I_FNOMIN], coef[I_LFZO], fz_n)
    mu_x = _mu(coef[I_PDX1], coef[I_PDX2], coef[I_LMUX], dfz)
    return mu_x, _mu(coef[I_PDY1], coef[I_PDY2], coef[I_LMUY], dfz)


@_kernel
def cornering_stiffness(coef, fz_n, mu_scale=1.0):
    """dFy/dtan α at zero slip [N/rad], positive; 0 for fz_n ≤ 0 or mu_scale ≤ 0.

    Independent of mu_scale > 0 (friction scaling moves the peak, not the initial slope).
    """
    if fz_n <= 0.0 or mu_scale <= 0.0:
        return 0.0
    fz0, _, fz_shape, load_ratio = _load_state(coef[I_FNOMIN], coef[I_LFZO], fz_n)
    return _ky(coef[I_PKY1], coef[I_PKY2], coef[I_LKY], fz0, fz_shape) * load_ratio


@_kernel
def longitudinal_stiffness(coef, fz_n):
    """dFx/dκ at zero slip [N per unit slip], positive; 0 for fz_n ≤ 0."""
    if fz_n <= 0.0:
        return 0.0
    _, dfz, fz_shape, load_ratio = _load_state(coef[I_FNOMIN], coef[I_LFZO], fz_n)
    k_x = _kx(coef[I_PKX1], coef[I_PKX2], coef[I_PKX3], coef[I_LKX], fz_shape, dfz)
    return k_x * load_ratio


@_kernel
def relaxation_lengths(coef, fz_n):
    """(σκ, σα) [m], MF 5.2 PTX1..3 / PTY1..2, each ≥ SIGMA_MIN_M.

    σκ = Fz·(PTX1 + PTX2·dfz)·exp(−PTX3·dfz)·R0/Fz0'·LSGKP,
    σα = PTY1·sin(2·atan(Fz/(PTY2·Fz0')))·R0·LFZO·LSGAL; a lifted wheel gets the floor.
    """
    if fz_n <= 0.0:
        return SIGMA_MIN_M, SIGMA_MIN_M
    fz0, dfz, fz_shape, _ = _load_state(coef[I_FNOMIN], coef[I_LFZO], fz_n)
    r0 = coef[I_UNLOADED_RADIUS]
    sigma_kappa = (
        fz_shape
        * (coef[I_PTX1] + coef[I_PTX2] * dfz)
        * _exp(-coef[I_PTX3] * dfz)
        * r0
        / fz0
        * coef[I_LSGKP]
    )
    u = fz_shape / (coef[I_PTY2] * fz0)
    sigma_alpha = coef[I_PTY1] * (2.0 * u / (1.0 + u * u)) * r0 * coef[I_LFZO] * coef[I_LSGAL]
    return max(sigma_kappa, SIGMA_MIN_M), max(sigma_alpha, SIGMA_MIN_M)


@_kernel
def rolling_resistance_coefficient(coef):
    """Free-rolling resistance force per unit load, QSY1·LMY [-] (My = −R0·Fz·this).

    QSY2 (dependence on Fx) is parsed but not applied.
    """
    return coef[I_QSY1] * coef[I_LMY]


@functools.lru_cache(maxsize=16)
def load_tire(path: str) -> TireParams:
    """A tyre file, parsed once per process (a batch reads each file once)."""
    return TireParams.from_tir(Path(path))
