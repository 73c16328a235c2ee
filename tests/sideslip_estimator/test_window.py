"""The sliding window: the last N rows in push order, one contiguous read-only view."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_estimator.window import SampleWindow


def _push_range(window: SampleWindow, start: int, count: int) -> None:
    for k in range(start, start + count):
        window.push(np.full(window.width, float(k)), stamp_ns=1000 * k)


@settings(max_examples=200, deadline=None)
@given(
    length=st.integers(1, 12),
    width=st.integers(1, 4),
    values=st.lists(st.floats(-1e6, 1e6), min_size=0, max_size=60),
)
def test_window_holds_the_last_n_pushed_rows_in_order_for_any_push_sequence(
    length: int, width: int, values: list[float]
) -> None:
    window = SampleWindow(length, width)
    pushed_rows, pushed_stamps = [], []
    for k, v in enumerate(values):
        row = v + np.arange(width, dtype=float)
        window.push(row, stamp_ns=7 * k + 3)
        pushed_rows.append(row)
        pushed_stamps.append(7 * k + 3)
        expected = np.array(pushed_rows[-length:]).reshape(-1, width)
        assert len(window) == min(k + 1, length)
        assert window.full == (k + 1 >= length)
        np.testing.assert_array_equal(window.rows(), expected)
        np.testing.assert_array_equal(window.stamps_ns(), pushed_stamps[-length:])
    if not values:
        assert len(window) == 0 and window.rows().shape == (0, width)


def test_window_is_not_full_until_length_rows_were_pushed() -> None:
    window = SampleWindow(5, 2)
    for k in range(4):
        window.push([k, k], k)
        assert not window.full
    window.push([4, 4], 4)
    assert window.full and len(window) == 5
    window.push([5, 5], 5)  # stays full, the oldest falls out
    assert window.full and len(window) == 5
    np.testing.assert_array_equal(window.stamps_ns(), [1, 2, 3, 4, 5])


def test_clear_empties_the_window_and_refills_from_scratch() -> None:
    window = SampleWindow(4, 1)
    _push_range(window, 0, 7)
    window.clear()
    assert len(window) == 0 and not window.full
    assert window.rows().shape == (0, 1) and window.stamps_ns().shape == (0,)
    _push_range(window, 100, 2)
    np.testing.assert_array_equal(window.rows()[:, 0], [100.0, 101.0])
    np.testing.assert_array_equal(window.stamps_ns(), [100_000, 101_000])


def test_rows_and_stamps_are_read_only_views_that_leave_the_buffer_writable() -> None:
    window = SampleWindow(3, 2)
    _push_range(window, 0, 5)
    rows, stamps = window.rows(), window.stamps_ns()
    assert not rows.flags.writeable and not stamps.flags.writeable
    assert rows.flags.c_contiguous and stamps.flags.c_contiguous
    with pytest.raises(ValueError, match="read-only"):
        rows[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        stamps[0] = 1
    _push_range(window, 5, 1)  # pushing still works after a view was handed out
    np.testing.assert_array_equal(window.rows()[:, 0], [3.0, 4.0, 5.0])


def test_rows_is_a_view_not_a_copy() -> None:
    window = SampleWindow(100, 6)
    _push_range(window, 0, 250)
    assert np.shares_memory(window.rows(), window._rows)
    assert window.rows().dtype == np.float64 and window.stamps_ns().dtype == np.int64


@pytest.mark.parametrize(("length", "width"), [(0, 6), (100, 0), (-1, 1)])
def test_window_of_non_positive_size_is_refused(length: int, width: int) -> None:
    with pytest.raises(ValueError, match=f"{length} x {width}"):
        SampleWindow(length, width)


def test_row_of_the_wrong_width_is_refused() -> None:
    window = SampleWindow(3, 6)
    with pytest.raises(ValueError):
        window.push(np.zeros(5), 0)
