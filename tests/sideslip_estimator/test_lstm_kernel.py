"""The compiled LSTM kernel's tanh: accuracy, symmetry and bounds (the step itself is
checked against torch in test_streaming.py)."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from sideslip_estimator.lstm_kernel import TANH_CLAMP, tanh_array


def kernel_tanh(x: np.ndarray) -> np.ndarray:
    x = np.ascontiguousarray(x, dtype=np.float32)
    out = np.empty_like(x)
    tanh_array(x, out)
    return out


def test_tanh_is_as_accurate_as_numpys_float32_tanh() -> None:
    x = np.linspace(-3 * TANH_CLAMP, 3 * TANH_CLAMP, 2_000_001, dtype=np.float32)
    exact = np.tanh(x.astype(np.float64))
    ours = np.abs(kernel_tanh(x) - exact).max()
    numpys = np.abs(np.tanh(x) - exact).max()
    # float32 rounding (half an ulp: 3e-8 near ±1) plus the fit's 7.7e-9.
    assert ours <= 1e-7
    assert ours <= 1.5 * numpys


@given(st.floats(-1e6, 1e6, allow_nan=False, width=32))
def test_tanh_is_odd_and_bounded(x: float) -> None:
    pos, neg = kernel_tanh(np.array([x, -x]))
    assert pos == -neg
    assert -1.0 <= pos <= 1.0
    assert np.sign(pos) == np.sign(x) or pos == 0.0
