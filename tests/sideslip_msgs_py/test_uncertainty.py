"""The per-sample σ model: its formula, its checks and its round trip through a model file."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sideslip_msgs_py.uncertainty import FitRange, Uncertainty, UncertaintyError, terms

UNC = Uncertainty((1e-8, 2.5e-4, 8e-8, 1.5e-4), 1.09)


def test_the_variance_is_the_scaled_sum_of_the_terms() -> None:
    v, a_y, r = 20.0, 3.0, 0.1
    beta_rate = a_y / v - r
    expected = 1.09**2 * (1e-8 + 2.5e-4 / v**2 + 8e-8 * a_y**2 + 1.5e-4 * beta_rate**2)
    assert UNC.variance_of(v, a_y, r) == pytest.approx(expected, rel=1e-12)
    assert UNC.variance([v], [a_y], [r])[0] == pytest.approx(expected, rel=1e-12)
    assert terms([0.2], [0.0], [0.0])[0, 1] == 1.0  # speed floored at 1 m/s


@given(v=st.floats(0.0, 80.0), a_y=st.floats(-15.0, 15.0), r=st.floats(-1.5, 1.5))
def test_sigma_is_finite_positive_and_the_same_on_both_paths(
    v: float, a_y: float, r: float
) -> None:
    one = UNC.variance_of(v, a_y, r)
    assert math.isfinite(one) and one > 0.0
    assert UNC.variance([v], [a_y], [r])[0] == pytest.approx(one, rel=1e-12)
    # Mirror symmetry: turning left or right gives the same σ.
    assert UNC.variance_of(v, -a_y, -r) == pytest.approx(one, rel=1e-12)


@pytest.mark.parametrize(
    ("data", "named"),
    [
        ({"coefficients": [1, 2, 3], "scale": 1.0}, "coefficients must be 4"),
        ({"coefficients": [1, -2, 3, 4], "scale": 1.0}, "coefficients must be 4"),
        ({"coefficients": [0, 0, 0, 0], "scale": 1.0}, "all coefficients are 0"),
        ({"coefficients": [1, 2, 3, 4], "scale": 0.0}, "scale must be"),
        ({"coefficients": [1, 2, 3, 4], "scale": 1.0, "kind": "ensemble"}, "unknown kind"),
        ({"coefficients": [1, 2, 3, 4], "scale": 1.0, "extra": 1}, "unknown key"),
        ({"coefficients": [1, 2, 3, 4], "scale": 1.0, "fit_range": [1, 2]}, "fit_range must be"),
        (
            {"coefficients": [1, 2, 3, 4], "scale": 1.0, "fit_range": {"outside_scale": 1.0}},
            "fit_range: keys must be",
        ),
        (
            {
                "coefficients": [1, 2, 3, 4],
                "scale": 1.0,
                "fit_range": {
                    "lateral_acceleration_mps2": float("nan"),
                    "beta_rate_radps": 0.1,
                    "outside_scale": 1.2,
                    "window_steps": 100,
                },
            },
            "lateral_acceleration_mps2 must be finite",
        ),
    ],
)
def test_a_bad_uncertainty_model_is_refused_naming_the_field(data: dict, named: str) -> None:
    with pytest.raises(UncertaintyError, match=named):
        Uncertainty.from_dict(data)


RANGED = Uncertainty(UNC.coefficients, 0.8, fit_range=FitRange(4.0, 0.05, 1.3))


@given(v=st.floats(0.0, 80.0), a_y=st.floats(-15.0, 15.0), r=st.floats(-1.5, 1.5))
def test_beyond_the_fit_range_sigma_takes_the_larger_scale(v: float, a_y: float, r: float) -> None:
    one, beyond = RANGED.variance_of_window([v], [a_y], [r])
    assert RANGED.variance([v], [a_y], [r])[0] == pytest.approx(one, rel=1e-12)
    assert RANGED.variance_of_window([v], [-a_y], [-r])[0] == pytest.approx(one, rel=1e-12)
    plain = Uncertainty(UNC.coefficients, 0.8).variance_of(v, a_y, r)
    assert RANGED.variance_of(v, a_y, r) == pytest.approx(plain, rel=1e-12)
    assert beyond == bool(RANGED.fit_range.beyond([v], [a_y], [r])[0])  # type: ignore[union-attr]
    assert one == pytest.approx(plain * (1.3 / 0.8) ** 2 if beyond else plain, rel=1e-12)


def test_sigma_stays_wide_while_the_window_holds_a_sample_beyond_the_range() -> None:
    unc = Uncertainty(UNC.coefficients, 0.8, fit_range=FitRange(4.0, 0.5, 1.6, window_steps=5))
    v, r = np.full(12, 20.0), np.zeros(12)
    a_y = np.zeros(12)
    a_y[3] = 6.0  # one sample beyond |a_y| ≤ 4: samples 3..7 see it in their window
    wide = unc.variance(v, a_y, r) > 1.01 * Uncertainty(UNC.coefficients, 0.8).variance(v, a_y, r)
    assert wide.tolist() == [False] * 3 + [True] * 5 + [False] * 4
    # A new run restarts the window: what lay beyond in the last run is forgotten.
    run = np.repeat([0, 1], 6)
    wide_runs = unc.fit_range.window_beyond(v, a_y, r, run)  # type: ignore[union-attr]
    assert wide_runs.tolist() == [False] * 3 + [True] * 3 + [False] * 6
    # The estimator's path gives the newest sample of each window the same σ.
    online = [unc.variance_of_window(v[max(0, k - 4) : k + 1], a_y[max(0, k - 4) : k + 1],
                                     r[max(0, k - 4) : k + 1])[0] for k in range(12)]  # fmt: skip
    assert online == pytest.approx(unc.variance(v, a_y, r).tolist(), rel=1e-12)


def test_an_outside_scale_below_the_cars_own_never_narrows_sigma() -> None:
    narrower = Uncertainty(UNC.coefficients, 0.8, fit_range=FitRange(4.0, 0.05, 0.5))
    plain = Uncertainty(UNC.coefficients, 0.8)
    assert narrower.variance_of_window([20.0], [9.0], [0.4]) == (
        plain.variance_of(20.0, 9.0, 0.4),
        True,
    )
    assert narrower.variance([20.0], [9.0], [0.4])[0] == pytest.approx(
        plain.variance_of(20.0, 9.0, 0.4), rel=1e-12
    )


def test_the_fit_range_spans_the_samples_at_speed_and_survives_the_model_file() -> None:
    rng = np.random.default_rng(0)
    v = np.concatenate([rng.uniform(5.0, 30.0, 5000), np.zeros(50)])  # parked: ignored
    a_y = np.concatenate([rng.uniform(-3.0, 3.0, 5000), np.full(50, 9.0)])
    r = a_y / np.maximum(v, 1.0)  # steady cornering: β̇ ≈ 0
    fit = FitRange.of_samples(v, a_y, r, outside_scale=1.2, window_steps=100)
    assert 2.9 < fit.lateral_acceleration_mps2 <= 3.0
    assert fit.beta_rate_radps < 1e-9 and fit.window_steps == 100
    unc = Uncertainty(UNC.coefficients, 0.9, fit_range=fit)
    assert Uncertainty.from_dict(unc.to_dict()) == unc
    assert "fit_range" not in UNC.to_dict()
    with pytest.raises(UncertaintyError, match="no sample at 1 m/s"):
        FitRange.of_samples([0.5], [1.0], [0.0], outside_scale=1.0, window_steps=1)
    with pytest.raises(UncertaintyError, match="window_steps must be an integer"):
        FitRange(1.0, 1.0, 1.0, window_steps=0)


def test_window_steps_from_json_may_be_an_integral_float_and_nothing_else() -> None:
    assert FitRange(1.0, 1.0, 1.0, window_steps=100.0).window_steps == 100  # type: ignore[arg-type]
    for bad in (99.5, True, float("inf")):
        with pytest.raises(UncertaintyError, match="window_steps must be an integer"):
            FitRange(1.0, 1.0, 1.0, window_steps=bad)  # type: ignore[arg-type]
    with pytest.raises(UncertaintyError, match="outside_scale must be finite"):
        FitRange(1.0, 1.0, True)  # type: ignore[arg-type]


def test_a_scalar_sample_and_run_ids_that_do_not_fit_are_handled() -> None:
    ranged = Uncertainty(UNC.coefficients, 0.8, fit_range=FitRange(4.0, 0.5, 1.6, window_steps=3))
    one = ranged.variance(20.0, 9.0, 0.4)
    assert np.shape(one) == () and one == pytest.approx(
        ranged.variance_of_window([20.0], [9.0], [0.4])[0]
    )
    fit = ranged.fit_range
    assert fit is not None
    with pytest.raises(UncertaintyError, match="one id per sample: 2 ids for 3 samples"):
        fit.window_beyond([20.0] * 3, [0.0] * 3, [0.0] * 3, run=[0, 0])
    with pytest.raises(UncertaintyError, match="run ids must be contiguous"):
        fit.window_beyond([20.0] * 3, [0.0] * 3, [0.0] * 3, run=[0, 1, 0])


def test_given_window_flags_override_what_the_samples_alone_would_say() -> None:
    """Scored samples lack their window's first rows: flags computed on the whole run."""
    ranged = Uncertainty(UNC.coefficients, 0.8, fit_range=FitRange(4.0, 0.5, 1.6, window_steps=3))
    plain = ranged.variance([20.0, 20.0], [0.0, 0.0], [0.0, 0.0])
    flagged = ranged.variance([20.0, 20.0], [0.0, 0.0], [0.0, 0.0], beyond=[True, False])
    assert flagged == pytest.approx(plain * np.array([4.0, 1.0]))


@given(
    a_y=st.lists(st.floats(-9.0, 9.0), min_size=1, max_size=8),
    v=st.floats(0.0, 40.0),
    r=st.floats(-0.6, 0.6),
)
def test_the_estimators_window_check_agrees_with_the_per_sample_flags(
    a_y: list[float], v: float, r: float
) -> None:
    fit = FitRange(4.0, 0.1, 2.0, window_steps=5)
    a = np.asarray(a_y)
    vs, rs = np.full(a.size, v), np.full(a.size, r)
    assert fit.reaches_beyond(vs, a, rs) == bool(fit.beyond(vs[-5:], a[-5:], rs[-5:]).any())


DESCRIBED = Uncertainty((0.0, 4e-5, 1e-7, 3e-4), 1.4)


def test_the_sigma_for_described_car_files_is_chosen_only_for_them_and_survives_the_file() -> None:
    unc = Uncertainty(UNC.coefficients, 0.9, described=DESCRIBED)
    assert unc.for_axles("description") is DESCRIBED
    for other in ("vehicle", "recordings"):
        assert unc.for_axles(other) is unc
    assert UNC.for_axles("description") is UNC  # none stored: the one σ for every file
    assert Uncertainty.from_dict(unc.to_dict()) == unc
    assert "described" not in UNC.to_dict()
    with pytest.raises(UncertaintyError, match="fit_range may not have a described"):
        Uncertainty(UNC.coefficients, 0.9, fit_range=FitRange(4.0, 0.05, 1.3), described=DESCRIBED)
    ratio = unc.for_axles("description").variance_of(20.0, 3.0, 0.1) / unc.variance_of(
        20.0, 3.0, 0.1
    )
    assert ratio != pytest.approx(1.0)


@pytest.mark.parametrize(
    ("described", "named"),
    [
        ({"coefficients": [1, 2, 3], "scale": 1.0}, "uncertainty.described: coefficients"),
        ([1, 2], "uncertainty.described must be a JSON object"),
        (
            {**DESCRIBED.to_dict(), "described": DESCRIBED.to_dict()},
            "uncertainty.described may not have a described or fit_range",
        ),
    ],
)
def test_a_bad_sigma_for_described_files_is_refused_naming_it(
    described: object, named: str
) -> None:
    with pytest.raises(UncertaintyError, match=named):
        Uncertainty.from_dict({**UNC.to_dict(), "described": described})
