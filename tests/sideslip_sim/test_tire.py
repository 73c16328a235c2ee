"""Magic Formula tyre forces: symmetry, limits, load sensitivity and the shipped tyre."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

try:
    from sideslip_sim import inline_math, tire, tire_forces
except ImportError:  # package not installed yet: use the source tree
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "sideslip_sim"))
    from sideslip_sim import inline_math, tire, tire_forces

PARAMS = tire.TireParams.from_tir()
COEF = PARAMS.coefficients()
FZ0 = PARAMS.fnomin_n

loads = st.floats(min_value=1.0, max_value=3.0 * FZ0)
slips = st.floats(min_value=-3.0, max_value=3.0)
mus = st.floats(min_value=0.05, max_value=1.5)


def forces(fz, kappa, tan_alpha, mu=1.0, coef=COEF):
    return tire_forces.combined_forces(coef, fz, kappa, tan_alpha, mu)


def peak_fy(fz, mu=1.0, coef=COEF):
    alphas = np.linspace(0.0, 0.6, 3001)
    fy = np.array([forces(fz, 0.0, math.tan(a), mu, coef)[1] for a in alphas])
    return fy.max(), alphas[fy.argmax()], alphas, fy


# ----------------------------------------------------------------------- packing


def test_index_constants_match_the_coefficient_layout():
    for index, key in enumerate(tire.COEFFICIENT_KEYS):
        assert getattr(tire, f"I_{key}") == index
    assert tire.N_COEFFICIENTS == len(tire.COEFFICIENT_KEYS) == len(set(tire.COEFFICIENT_KEYS))


def test_coefficients_are_a_float64_array_in_key_order():
    assert COEF.dtype == np.float64 and COEF.shape == (tire.N_COEFFICIENTS,)
    assert COEF[tire.I_PKY1] == PARAMS["PKY1"] == -14.95
    assert PARAMS.unloaded_radius_m == 0.313 and PARAMS.vertical_stiffness_n_per_m > 0


def test_with_values_replaces_known_keys_and_refuses_unknown_or_invalid():
    assert PARAMS.with_values(LMUY=0.8)["LMUY"] == 0.8
    with pytest.raises(KeyError, match="PKY9"):
        PARAMS.with_values(PKY9=1.0)
    with pytest.raises(ValueError, match="FNOMIN"):
        PARAMS.with_values(FNOMIN=0.0)


def test_kernels_are_callable_from_other_njit_code():
    @njit
    def four_wheels(coef, fz):
        total = 0.0
        for _ in range(4):
            fx, fy = tire_forces.combined_forces(coef, fz, 0.02, 0.03, 1.0)
            total += fx + fy + tire_forces.cornering_stiffness(coef, fz)
            total += (
                tire_forces.longitudinal_stiffness(coef, fz)
                + tire_forces.relaxation_lengths(coef, fz)[0]
            )
            total += tire_forces.rolling_resistance_coefficient(coef)
        return total

    assert math.isfinite(four_wheels(COEF, 4000.0))


# ------------------------------------------------------------- the shipped tyre


def test_shipped_tyre_has_passenger_car_numbers_at_nominal_load():
    mu_x, mu_y = tire_forces.friction_coefficients(COEF, FZ0)
    assert 0.9 <= mu_y <= 1.2 and 1.0 <= mu_x <= 1.4
    assert 40e3 <= tire_forces.cornering_stiffness(COEF, FZ0) <= 90e3
    peak, alpha_peak, alphas, fy = peak_fy(FZ0)
    assert peak == pytest.approx(mu_y * FZ0, rel=1e-6)
    # The book tyre has a flat top (C_y = 1.193): 95 % of the peak by 5-10 deg, the
    # maximum itself near 15 deg.
    alpha_95 = alphas[np.argmax(fy >= 0.95 * peak)]
    assert math.radians(5.0) <= alpha_95 <= math.radians(10.0)
    assert math.radians(12.0) <= alpha_peak <= math.radians(17.0)


def test_relaxation_lengths_are_positive_and_lifted_wheel_gets_the_floor():
    sigma_kappa, sigma_alpha = tire_forces.relaxation_lengths(COEF, FZ0)
    assert sigma_kappa == pytest.approx(0.215, abs=0.01)
    assert sigma_alpha == pytest.approx(0.383, abs=0.01)
    assert tire_forces.relaxation_lengths(COEF, 0.0) == (
        tire_forces.SIGMA_MIN_M,
        tire_forces.SIGMA_MIN_M,
    )
    for fz in (1.0, 100.0, 2e3, 8e3, 1e6):
        assert min(tire_forces.relaxation_lengths(COEF, fz)) >= tire_forces.SIGMA_MIN_M


def test_rolling_resistance_coefficient_is_qsy1():
    assert tire_forces.rolling_resistance_coefficient(COEF) == pytest.approx(0.01)


# -------------------------------------------------------------------- symmetry


@given(fz=loads, kappa=slips, tan_alpha=slips, mu=mus)
def test_forces_are_odd_in_their_own_slip_and_even_in_the_other(fz, kappa, tan_alpha, mu):
    fx, fy = forces(fz, kappa, tan_alpha, mu)
    assert forces(fz, -kappa, tan_alpha, mu) == (-fx, fy)
    assert forces(fz, kappa, -tan_alpha, mu) == (fx, -fy)


@given(fz=loads, mu=mus)
def test_zero_slip_gives_exactly_zero_force(fz, mu):
    assert forces(fz, 0.0, 0.0, mu) == (0.0, 0.0)


@given(kappa=slips, tan_alpha=slips, mu=mus)
def test_force_never_points_against_the_slip(kappa, tan_alpha, mu):
    fx, fy = forces(FZ0, abs(kappa), abs(tan_alpha), mu)
    assert fx >= 0.0 and fy >= 0.0


@given(kappa=st.floats(1e-6, 0.2), tan_alpha=st.floats(1e-6, 0.2), mu=st.floats(0.3, 1.5))
def test_moderate_slip_gives_force_in_the_slip_direction(kappa, tan_alpha, mu):
    # "Moderate" relative to friction: mu_scale also scales the slip axis.
    fx, fy = forces(FZ0, kappa * mu, tan_alpha * mu, mu)
    assert fx > 0.0 and fy > 0.0


def test_iso_and_positive_sign_sets_give_the_same_forces():
    flipped = PARAMS.with_values(
        PDY1=-PARAMS["PDY1"], PDY2=-PARAMS["PDY2"], PKY1=-PARAMS["PKY1"]
    ).coefficients()
    for kappa, tan_alpha in [(0.0, 0.1), (0.05, -0.2), (-0.3, 0.04)]:
        assert forces(3000.0, kappa, tan_alpha, coef=flipped) == forces(3000.0, kappa, tan_alpha)


# ------------------------------------------------------------------ limits


@given(fz=st.floats(max_value=0.0, allow_nan=False), kappa=slips, tan_alpha=slips, mu=mus)
def test_lifted_wheel_gives_exactly_zero(fz, kappa, tan_alpha, mu):
    assert forces(fz, kappa, tan_alpha, mu) == (0.0, 0.0)


def test_zero_friction_gives_exactly_zero():
    assert forces(FZ0, 0.1, 0.1, 0.0) == (0.0, 0.0)


@pytest.mark.parametrize("mu", [0.3, 1.0])
@pytest.mark.parametrize("fz", [1000.0, 4000.0, 8000.0])
def test_resultant_stays_inside_the_friction_limit(fz, mu):
    mu_x, mu_y = tire_forces.friction_coefficients(COEF, fz)
    limit = 1.05 * max(mu_x, mu_y) * fz * mu
    grid = np.concatenate([-np.geomspace(1e-4, 3.0, 40), [0.0], np.geomspace(1e-4, 3.0, 40)])
    for kappa in grid:
        for tan_alpha in grid:
            fx, fy = forces(fz, kappa, tan_alpha, mu)
            assert math.hypot(fx, fy) <= limit


@given(
    fz=st.floats(min_value=1e-9, max_value=1e9),
    kappa=st.floats(min_value=-1e12, max_value=1e12),
    tan_alpha=st.floats(min_value=-1e12, max_value=1e12),
    mu=st.floats(min_value=1e-9, max_value=1e3),
)
@settings(max_examples=300)
def test_outputs_are_finite_for_extreme_inputs(fz, kappa, tan_alpha, mu):
    assert all(math.isfinite(v) for v in forces(fz, kappa, tan_alpha, mu))
    assert math.isfinite(tire_forces.cornering_stiffness(COEF, fz, mu))
    assert math.isfinite(tire_forces.longitudinal_stiffness(COEF, fz))
    assert all(math.isfinite(v) for v in tire_forces.relaxation_lengths(COEF, fz))


# ------------------------------------------------------------- combined slip


@pytest.mark.parametrize("alpha_deg", [1.0, 4.0, 10.0])
def test_lateral_force_falls_as_longitudinal_slip_grows(alpha_deg):
    tan_alpha = math.tan(math.radians(alpha_deg))
    kappas = np.linspace(0.0, 1.0, 201)
    fy = np.array([forces(FZ0, k, tan_alpha)[1] for k in kappas])
    assert np.all(np.diff(fy) <= 0.0) and fy[-1] < 0.5 * fy[0]


def test_longitudinal_force_falls_as_slip_angle_grows():
    tan_alphas = np.tan(np.radians(np.linspace(0.0, 30.0, 121)))
    fx = np.array([forces(FZ0, 0.05, t)[0] for t in tan_alphas])
    assert np.all(np.diff(fx) <= 0.0) and fx[-1] < 0.5 * fx[0]


# ---------------------------------------------------------- load sensitivity


def test_friction_coefficient_falls_with_load():
    loads_n = np.linspace(500.0, 12000.0, 50)
    mu = np.array([tire_forces.friction_coefficients(COEF, fz) for fz in loads_n])
    assert np.all(np.diff(mu[:, 0]) < 0.0) and np.all(np.diff(mu[:, 1]) < 0.0)
    peaks = np.array([peak_fy(fz)[0] / fz for fz in (2000.0, 4000.0, 6000.0)])
    assert np.all(np.diff(peaks) < 0.0)


def test_cornering_stiffness_grows_sub_linearly_with_load():
    loads_n = np.linspace(500.0, 8000.0, 40)
    stiffness = np.array([tire_forces.cornering_stiffness(COEF, fz) for fz in loads_n])
    assert np.all(np.diff(stiffness) > 0.0)
    assert np.all(np.diff(stiffness / loads_n) < 0.0)  # per newton of load: falls


@pytest.mark.parametrize("fz", [1500.0, 4000.0, 7000.0])
def test_slip_stiffnesses_are_the_slopes_at_zero_slip(fz):
    h = 1e-7
    assert forces(fz, 0.0, h)[1] / h == pytest.approx(
        tire_forces.cornering_stiffness(COEF, fz), 1e-5
    )
    assert forces(fz, h, 0.0)[0] / h == pytest.approx(
        tire_forces.longitudinal_stiffness(COEF, fz), 1e-5
    )
    assert tire_forces.cornering_stiffness(COEF, fz, 0.4) == tire_forces.cornering_stiffness(
        COEF, fz
    )


def test_forces_grow_in_proportion_to_load_beyond_the_fitted_range():
    f1 = forces(5 * FZ0, 0.1, 0.1)
    f2 = forces(10 * FZ0, 0.1, 0.1)
    assert f2[0] == pytest.approx(2 * f1[0]) and f2[1] == pytest.approx(2 * f1[1])


# ------------------------------------------------------------------ friction


@pytest.mark.parametrize("mu", [0.2, 0.5, 0.8])
def test_mu_scale_scales_the_peak_force_and_the_peak_slip(mu):
    peak, alpha_peak, _, _ = peak_fy(FZ0)
    peak_mu, alpha_peak_mu, _, _ = peak_fy(FZ0, mu)
    assert peak_mu == pytest.approx(mu * peak, rel=1e-4)
    assert math.tan(alpha_peak_mu) == pytest.approx(mu * math.tan(alpha_peak), abs=2e-3)


# ------------------------------------------------------------ four corners at once

# Combined-slip curvatures non-zero (the shipped tyre has REX*, REY* = 0, which takes the
# other copy of the loop) and PEX* = 0 (E = 0: the scalar code skips that term).
COEF_CURVED = PARAMS.with_values(
    REX1=0.3, REX2=-0.2, REY1=0.1, REY2=0.4, PEX1=0.0, PEX2=0.0, PEX3=0.0, RCX1=2.0
).coefficients()
wide_loads = st.one_of(
    st.floats(min_value=-1e4, max_value=3.0 * FZ0),
    st.floats(min_value=-1e9, max_value=1e9),
    st.sampled_from([0.0, -0.0, -1.0, 1e-300, 5e-324, 4.0 * FZ0, 1e12]),
)
wide_slips = st.one_of(
    st.floats(min_value=-3.0, max_value=3.0),
    st.floats(min_value=-1e12, max_value=1e12),
    st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e300, -1e300]),
)
wide_mus = st.one_of(
    st.floats(min_value=-1.0, max_value=3.0),
    st.floats(min_value=1e-9, max_value=1e3),
    st.sampled_from([0.0, -0.0, -1e-300, 1e-300, 1e-9, 1.0, 1e3]),
)


def same_force(got, want):
    if math.isnan(want):
        return math.isnan(got)
    return abs(got - want) <= 1e-12 * abs(want) + 1e-9


@given(
    fz=st.lists(wide_loads, min_size=4, max_size=4),
    kappa=st.lists(wide_slips, min_size=4, max_size=4),
    tan_alpha=st.lists(wide_slips, min_size=4, max_size=4),
    mu=wide_mus,
    curved=st.booleans(),
)
@settings(max_examples=500)
def test_combined_forces4_equals_four_scalar_calls(fz, kappa, tan_alpha, mu, curved):
    coef = COEF_CURVED if curved else COEF
    fx, fy = np.full(4, np.nan), np.full(4, np.nan)
    tire_forces.combined_forces4(
        coef, np.array(fz), np.array(kappa), np.array(tan_alpha), mu, fx, fy
    )
    for i in range(4):
        want_x, want_y = tire_forces.combined_forces(coef, fz[i], kappa[i], tan_alpha[i], mu)
        assert same_force(fx[i], want_x) and same_force(fy[i], want_y), (i, fx[i], fy[i])
        if fz[i] <= 0.0 or mu <= 0.0:
            assert fx[i] == 0.0 and fy[i] == 0.0


def test_combined_forces4_takes_strided_and_overlapping_arrays():
    fz = np.array([3000.0, 0.0, -5.0, 8000.0])
    kappa = np.array([0.05, -0.2, 0.1, -2.0])
    tan_alpha = np.array([-0.1, 0.02, 0.3, 0.5])
    want = [
        tire_forces.combined_forces(COEF, *args, 0.7)
        for args in zip(fz, kappa, tan_alpha, strict=True)
    ]
    strided = np.zeros((3, 8))
    strided[:, ::2] = fz, kappa, tan_alpha
    fx, fy = np.zeros(4), np.zeros(4)
    tire_forces.combined_forces4(
        COEF, strided[0, ::2], strided[1, ::2], strided[2, ::2], 0.7, fx, fy
    )
    inout = np.concatenate([fz, kappa, tan_alpha])  # fx over kappa, fy over fz
    tire_forces.combined_forces4(COEF, inout[:4], inout[4:8], inout[8:], 0.7, inout[4:8], inout[:4])
    for i, (want_x, want_y) in enumerate(want):
        assert same_force(fx[i], want_x) and same_force(fy[i], want_y)
        assert inout[4 + i] == fx[i] and inout[i] == fy[i]
    assert fx[1] == fx[2] == fy[1] == fy[2] == 0.0


# ------------------------------------------------------------ inline kernels


def test_inline_math_kernels_match_libm():
    x = np.concatenate([np.linspace(-50.0, 50.0, 20001), np.geomspace(1e-12, 1e12, 2000)])
    assert max(abs(inline_math.poly_atan(v) - math.atan(v)) for v in x) < 1e-15
    assert max(abs(inline_math.poly_atan(-v) + inline_math.poly_atan(v)) for v in x) == 0.0
    theta = np.linspace(-math.pi, math.pi, 20001)
    assert max(abs(inline_math.poly_sin(t) - math.sin(t)) for t in theta) < 1e-15
    assert max(abs(inline_math.poly_cos(t) - math.cos(t)) for t in theta) < 1e-15
    e = np.linspace(-16.0, 16.0, 20001)
    assert max(abs(inline_math.poly_exp(v) / math.exp(v) - 1.0) for v in e) < 1e-12
