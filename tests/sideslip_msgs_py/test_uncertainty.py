"""The per-sample σ model: its formula, its checks and its round trip through a model file."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sideslip_msgs_py.uncertainty import Uncertainty, UncertaintyError, terms

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
    ],
)
def test_a_bad_uncertainty_model_is_refused_naming_the_field(data: dict, named: str) -> None:
    with pytest.raises(UncertaintyError, match=named):
        Uncertainty.from_dict(data)
