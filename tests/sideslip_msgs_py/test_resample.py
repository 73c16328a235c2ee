"""Samples at another rate than the model's are resampled (anti-aliased when slowed
down) or refused naming both rates; samples at the model's rate pass unchanged."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py.resample import RateError, measured_step_s, to_step
from sideslip_msgs_py.sample import SampleArrays

STEP_S = 0.0025  # the model's 400 Hz


def _signal(rate_hz: float, seconds: float, tones: dict[float, float], t0_ns: int = 0):
    """Every channel the same sum of sines {frequency [Hz]: amplitude} at ``rate_hz``."""
    n = round(seconds * rate_hz)
    stamps = t0_ns + np.round(np.arange(n) * 1e9 / rate_hz).astype(np.int64)
    t = (stamps - stamps[0]) * 1e-9
    y = sum(a * np.sin(2 * math.pi * f * t) for f, a in tones.items())
    names = (
        "x_v_mps", "y_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m", "stl_rate_mps",
        "truth_v_x_mps", "truth_v_y_mps", "truth_yaw_rate_radps",
    )  # fmt: skip
    cols = {k: y.copy() for k in names}
    cols["x_v_mps"] = cols["truth_v_x_mps"] = 20.0 + y
    return SampleArrays(stamp_ns=stamps, **cols)


def test_samples_at_the_models_rate_pass_unchanged() -> None:
    s = _signal(400.0, 1.0, {2.0: 1.0})
    out = to_step(s, STEP_S)
    assert out.samples is s and out.note is None and out.source_rate_hz == pytest.approx(400.0)


@pytest.mark.parametrize("rate_hz", [50.0, 100.0, 200.0])
def test_a_slower_recording_is_interpolated_onto_the_models_grid(rate_hz: float) -> None:
    s = _signal(rate_hz, 2.0, {1.5: 1.0})
    out = to_step(s, STEP_S)
    assert out.note is not None and f"from {rate_hz:.1f} Hz to 400 Hz" in out.note
    new = out.samples
    assert np.all(np.diff(new.stamp_ns) == 2_500_000)
    assert new.stamp_ns[0] == s.stamp_ns[0] and new.stamp_ns[-1] <= s.stamp_ns[-1]
    t = (new.stamp_ns - new.stamp_ns[0]) * 1e-9
    exact = np.sin(2 * math.pi * 1.5 * t)
    # Linear interpolation of a 1.5-Hz sine: error below (ωh)²/8 of the amplitude.
    bound = (2 * math.pi * 1.5 / rate_hz) ** 2 / 8 + 1e-12
    assert np.max(np.abs(new.y_a_mps2 - exact)) <= bound


def test_a_faster_recording_is_low_passed_so_nothing_folds_back() -> None:
    # A 1000-Hz recording: a 2-Hz manoeuvre plus a 300-Hz vibration, which 400 Hz can
    # not hold (its Nyquist frequency is 200 Hz): plain decimation would fold it to 100 Hz.
    s = _signal(1000.0, 3.0, {2.0: 1.0, 300.0: 0.5})
    out = to_step(s, STEP_S)
    assert out.note is not None and "low-pass" in out.note
    new = out.samples
    t = (new.stamp_ns - new.stamp_ns[0]) * 1e-9
    inner = slice(200, -200)  # away from the ends of the zero-phase filter
    residual = new.y_a_mps2[inner] - np.sin(2 * math.pi * 2.0 * t[inner])
    assert np.sqrt(np.mean(residual**2)) < 0.01  # of a 0.5 vibration: > 35x down
    naive = np.interp(new.stamp_ns, s.stamp_ns, s.y_a_mps2)[inner]
    assert np.sqrt(np.mean((naive - np.sin(2 * math.pi * 2.0 * t[inner])) ** 2)) > 0.1


@pytest.mark.parametrize("rate_hz", [30.0, 2000.0])
def test_rates_outside_50_to_1000_hz_are_refused_naming_both(rate_hz: float) -> None:
    with pytest.raises(RateError, match=rf"{rate_hz:.1f} Hz.*400 Hz"):
        to_step(_signal(rate_hz, 1.0, {1.0: 1.0}), STEP_S)


def test_gaps_stay_gaps_and_nan_stays_unknown() -> None:
    a = _signal(200.0, 1.0, {1.0: 1.0})
    b = _signal(200.0, 1.0, {1.0: 1.0}, t0_ns=int(a.stamp_ns[-1]) + 500_000_000)
    cols = {k: np.concatenate([getattr(a, k), getattr(b, k)]) for k in vars(a)}
    cols["yaw_rate_radps"][50] = np.nan
    out = to_step(SampleArrays(**cols), STEP_S).samples
    steps = np.diff(out.stamp_ns)
    assert set(steps.tolist()) == {2_500_000, int(b.stamp_ns[0] - out.stamp_ns[steps.argmax()])}
    assert np.count_nonzero(steps > 2_500_000) == 1  # one gap, nothing invented inside it
    bad = ~np.isfinite(out.yaw_rate_radps)
    # Only samples within one 5-ms source step of the NaN are unknown.
    near = np.abs(out.stamp_ns - a.stamp_ns[50]) < 5_000_000
    assert bad.any() and np.array_equal(bad, near)
    assert np.isfinite(out.y_a_mps2).all()


@settings(max_examples=30, deadline=None)
@given(rate_hz=st.floats(50.0, 1000.0), seconds=st.floats(0.2, 2.0))
def test_resampled_stamps_are_the_models_grid_within_the_recording(
    rate_hz: float, seconds: float
) -> None:
    s = _signal(rate_hz, seconds, {1.0: 1.0}, t0_ns=10**12)
    new = to_step(s, STEP_S).samples
    step = measured_step_s(new.stamp_ns)
    if new is not s:
        assert np.all(np.diff(new.stamp_ns) == 2_500_000) or len(new) == 0
    else:
        assert step is not None and abs(step / STEP_S - 1) <= 0.01
    if len(new):
        assert s.stamp_ns[0] <= new.stamp_ns[0] and new.stamp_ns[-1] <= s.stamp_ns[-1]
        assert np.isfinite(new.y_a_mps2).all()
