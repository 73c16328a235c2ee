"""Steady-state tyre forces: Pacejka Magic Formula 5.2, pure and combined slip, camber 0.

Equations: MF 5.2 as in H. B. Pacejka, "Tyre and Vehicle Dynamics", 2nd ed. (2006), §4.3
(the form used by MF-Tyre 5.2 / PAC2002 ``.tir`` files), with load sensitivity through
dfz = (Fz − Fz0')/Fz0', Fz0' = FNOMIN·LFZO, and combined slip through the weighting
functions Gxα (RBX1, RBX2, RCX1, REX1, REX2) and Gyκ (RBY1, RBY2, RCY1, REY1, REY2).
The coefficients, their packing and the ``.tir`` loader are in :mod:`sideslip_sim.tire`.

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
:meth:`~sideslip_sim.tire.TireParams.coefficients`; index it with the ``I_<KEY>``
constants of :mod:`sideslip_sim.tire`. atan, sin, cos and exp come from
:mod:`sideslip_sim.inline_math` (polynomials, inlined: faster than libm calls).
:func:`combined_forces4` computes the four corners of a car in one call, vectorised
(AVX2: one lane per corner); it gives the same forces as four :func:`combined_forces` calls.
The scalar function is the readable reference of the equations; the vehicle model calls
the vectorised one (about 3× faster), and a property test holds the two equal, so an edit
to one must be made to both. That pair is why this module runs past ~400 lines: the two
must be read side by side, and the import of the index constants alone takes ~50 lines.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from sideslip_sim.inline_math import inline_njit, poly_atan, poly_cos, poly_exp, poly_sin
from sideslip_sim.tire import (
    I_FNOMIN,
    I_LCX,
    I_LCY,
    I_LEX,
    I_LEY,
    I_LFZO,
    I_LKX,
    I_LKY,
    I_LMUX,
    I_LMUY,
    I_LMY,
    I_LSGAL,
    I_LSGKP,
    I_LXAL,
    I_LYKA,
    I_PCX1,
    I_PCY1,
    I_PDX1,
    I_PDX2,
    I_PDY1,
    I_PDY2,
    I_PEX1,
    I_PEX2,
    I_PEX3,
    I_PEY1,
    I_PEY2,
    I_PKX1,
    I_PKX2,
    I_PKX3,
    I_PKY1,
    I_PKY2,
    I_PTX1,
    I_PTX2,
    I_PTX3,
    I_PTY1,
    I_PTY2,
    I_QSY1,
    I_RBX1,
    I_RBX2,
    I_RBY1,
    I_RBY2,
    I_RCX1,
    I_RCY1,
    I_REX1,
    I_REX2,
    I_REY1,
    I_REY2,
    I_UNLOADED_RADIUS,
)

__all__ = [
    "SIGMA_MIN_M",
    "combined_forces",
    "combined_forces4",
    "cornering_stiffness",
    "friction_coefficients",
    "longitudinal_stiffness",
    "relaxation_lengths",
    "rolling_resistance_coefficient",
]

# Public kernels: numpy error model (a zero divisor gives inf/nan, never raises inside an
# integrator) and FMA contraction (faster and at least as accurate; sign symmetric). Private
# helpers use inline_njit, so each public kernel compiles to one function.
_kernel = njit(cache=True, error_model="numpy")

SIGMA_MIN_M = 0.05  # floor of the relaxation lengths; also what a lifted wheel gets [m]
_DFZ_MAX = 3.0  # load dependence frozen beyond Fz = (1 + _DFZ_MAX)·Fz0'
_SLIP_ARG_MAX = 1.0e6  # |B·slip| clip: atan is flat there, and it keeps inf out of E-terms
_EPS = 1.0e-9  # keeps B = K/(C·D) finite when D = 0 (μ floored, or zero friction)


@inline_njit
def _load_state(fnomin: float, lfzo: float, fz_n: float) -> tuple[float, float, float, float]:
    """(Fz0', dfz frozen at _DFZ_MAX, load actually used for the shape, ratio Fz/that)."""
    fz0 = fnomin * lfzo
    fz_shape = min(fz_n, (1.0 + _DFZ_MAX) * fz0)
    return fz0, fz_shape / fz0 - 1.0, fz_shape, fz_n / fz_shape


@inline_njit
def _mf_angle(x: float, c: float, e: float) -> float:
    """The Magic Formula's angle C·atan(x − E·(x − atan x)) for x = B·slip (x clipped)."""
    x = min(max(x, -_SLIP_ARG_MAX), _SLIP_ARG_MAX)
    if e != 0.0:
        x = x - e * (x - poly_atan(x))
    return c * poly_atan(x)


@inline_njit
def _sign(value: float) -> float:
    return -1.0 if value < 0.0 else 1.0


@inline_njit
def _kx(pkx1: float, pkx2: float, pkx3: float, lkx: float, fz_shape: float, dfz: float) -> float:
    """Longitudinal slip stiffness at the shape load [N per unit slip], ≥ 0."""
    k = fz_shape * _sign(pkx1) * (pkx1 + pkx2 * dfz) * poly_exp(pkx3 * dfz)
    return max(k * lkx, 0.0)


@inline_njit
def _ky(pky1: float, pky2: float, lky: float, fz0: float, fz_shape: float) -> float:
    """Cornering stiffness at the shape load [N/rad]; sin(2·atan u) = 2u/(1 + u²)."""
    u = fz_shape / (pky2 * fz0)
    return abs(pky1) * fz0 * (2.0 * u / (1.0 + u * u)) * lky


@inline_njit
def _mu(pd1: float, pd2: float, lmu: float, dfz: float) -> float:
    """Peak friction at the shape load, sign-normalised (ISO files have PDY1 < 0), ≥ 0."""
    return max(_sign(pd1) * (pd1 + pd2 * dfz) * lmu, 0.0)


@_kernel
def combined_forces(
    coef: np.ndarray, fz_n: float, kappa: float, tan_alpha: float, mu_scale: float
) -> tuple[float, float]:
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
    fx0 = d_x * poly_sin(_mf_angle(b_x * kappa, c_x, e_x))

    # Pure lateral slip (α* = tan α, as in MF 5.2).
    d_y = _mu(pdy1, pdy2, lmuy, dfz) * fz_shape
    e_y = min((pey1 + pey2 * dfz) * ley, 1.0)
    b_y = _ky(pky1, pky2, lky, fz0, fz_shape) / (c_y * d_y + _EPS)
    fy0 = d_y * poly_sin(_mf_angle(b_y * tan_alpha, c_y, e_y))

    # Combined-slip weights Gxα, Gyκ; cos(atan z) = 1/sqrt(1 + z²).
    r = rbx2 * kappa
    b_xa = rbx1 / math.sqrt(1.0 + r * r)
    g_xa = max(poly_cos(_mf_angle(b_xa * tan_alpha, rcx1, min(rex1 + rex2 * dfz, 1.0))), 0.0)
    r = rby2 * tan_alpha
    b_yk = rby1 / math.sqrt(1.0 + r * r)
    g_yk = max(poly_cos(_mf_angle(b_yk * kappa, rcy1, min(rey1 + rey2 * dfz, 1.0))), 0.0)

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


@inline_njit
def _mf_angle_lane(x: float, c: float, e: float, use_e: bool) -> float:
    """_mf_angle without a lane-dependent branch; use_e=False (a constant) drops the E-term."""
    x = min(max(x, -_SLIP_ARG_MAX), _SLIP_ARG_MAX)
    if use_e:
        x = x - e * (x - poly_atan(x))
    return c * poly_atan(x)


@inline_njit
def _forces_lanes(coef: np.ndarray, buf: types.CPointer, mu_scale: float, combined_e: bool) -> None:
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
        fx0 = d_x * poly_sin(_mf_angle_lane(b_x * kappa, c_x, e_x, True))

        d_y = _mu(pdy1, pdy2, lmuy, dfz) * fz_shape
        e_y = min((pey1 + pey2 * dfz) * ley, 1.0)
        b_y = _ky(pky1, pky2, lky, fz0, fz_shape) / (c_y * d_y + _EPS)
        fy0 = d_y * poly_sin(_mf_angle_lane(b_y * tan_alpha, c_y, e_y, True))

        r = rbx2 * kappa
        b_xa = rbx1 / math.sqrt(1.0 + r * r)
        e_xa = min(rex1 + rex2 * dfz, 1.0)
        g_xa = max(poly_cos(_mf_angle_lane(b_xa * tan_alpha, rcx1, e_xa, combined_e)), 0.0)
        r = rby2 * tan_alpha
        b_yk = rby1 / math.sqrt(1.0 + r * r)
        e_yk = min(rey1 + rey2 * dfz, 1.0)
        g_yk = max(poly_cos(_mf_angle_lane(b_yk * kappa, rcy1, e_yk, combined_e)), 0.0)

        scale = mu_scale * load_ratio
        fx = scale * g_xa * fx0
        fy = scale * g_yk * fy0
        buf[i] = 0.0 if lifted else fx
        buf[4 + i] = 0.0 if lifted else fy


@_kernel
def combined_forces4(
    coef: np.ndarray,
    fz_n: np.ndarray,
    kappa: np.ndarray,
    tan_alpha: np.ndarray,
    mu_scale: float,
    fx_out: np.ndarray,
    fy_out: np.ndarray,
) -> None:
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
def friction_coefficients(coef: np.ndarray, fz_n: float) -> tuple[float, float]:
    """Peak (μx, μy) of the pure-slip curves at load fz_n on the test surface [-]."""
    if fz_n <= 0.0:
        return 0.0, 0.0
    _, dfz, _, _ = _load_state(coef[I_FNOMIN], coef[I_LFZO], fz_n)
    mu_x = _mu(coef[I_PDX1], coef[I_PDX2], coef[I_LMUX], dfz)
    return mu_x, _mu(coef[I_PDY1], coef[I_PDY2], coef[I_LMUY], dfz)


@_kernel
def cornering_stiffness(coef: np.ndarray, fz_n: float, mu_scale: float = 1.0) -> float:
    """dFy/dtan α at zero slip [N/rad], positive; 0 for fz_n ≤ 0 or mu_scale ≤ 0.

    Independent of mu_scale > 0 (friction scaling moves the peak, not the initial slope).
    """
    if fz_n <= 0.0 or mu_scale <= 0.0:
        return 0.0
    fz0, _, fz_shape, load_ratio = _load_state(coef[I_FNOMIN], coef[I_LFZO], fz_n)
    return _ky(coef[I_PKY1], coef[I_PKY2], coef[I_LKY], fz0, fz_shape) * load_ratio


@_kernel
def longitudinal_stiffness(coef: np.ndarray, fz_n: float) -> float:
    """dFx/dκ at zero slip [N per unit slip], positive; 0 for fz_n ≤ 0."""
    if fz_n <= 0.0:
        return 0.0
    _, dfz, fz_shape, load_ratio = _load_state(coef[I_FNOMIN], coef[I_LFZO], fz_n)
    k_x = _kx(coef[I_PKX1], coef[I_PKX2], coef[I_PKX3], coef[I_LKX], fz_shape, dfz)
    return k_x * load_ratio


@_kernel
def relaxation_lengths(coef: np.ndarray, fz_n: float) -> tuple[float, float]:
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
        * poly_exp(-coef[I_PTX3] * dfz)
        * r0
        / fz0
        * coef[I_LSGKP]
    )
    u = fz_shape / (coef[I_PTY2] * fz0)
    sigma_alpha = coef[I_PTY1] * (2.0 * u / (1.0 + u * u)) * r0 * coef[I_LFZO] * coef[I_LSGAL]
    return max(sigma_kappa, SIGMA_MIN_M), max(sigma_alpha, SIGMA_MIN_M)


@_kernel
def rolling_resistance_coefficient(coef: np.ndarray) -> float:
    """Free-rolling resistance force per unit load, QSY1·LMY [-] (My = −R0·Fz·this).

    QSY2 (dependence on Fx) is parsed but not applied.
    """
    return coef[I_QSY1] * coef[I_LMY]
