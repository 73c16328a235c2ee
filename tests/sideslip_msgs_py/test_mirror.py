"""A mirrored run is what the car gives when driven the other way round: negation of the
registry's lateral channels, exact and its own inverse, and equal to the simulator's
response to the mirrored steering."""

from __future__ import annotations

import dataclasses

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from sideslip_msgs_py.channels import SENSOR, TRUTH
from sideslip_msgs_py.mirror import LATERAL_CHANNELS, mirrored
from sideslip_msgs_py.sample import SampleArrays

FINITE = st.floats(-1e6, 1e6, allow_nan=False)


def _samples(draw_columns: dict[str, np.ndarray], with_truth: bool) -> SampleArrays:
    n = len(next(iter(draw_columns.values())))
    cols = {"stamp_ns": np.arange(n, dtype=np.int64) * 2_500_000}
    for ch in SENSOR:
        cols[ch.name] = draw_columns[ch.name]
    for ch in TRUTH:
        cols[ch.name] = draw_columns[ch.name] if with_truth else None
    if with_truth:  # a moving car: β defined
        cols["truth_v_x_mps"] = np.abs(cols["truth_v_x_mps"]) + 1.0
    return SampleArrays(**cols)


@st.composite
def sample_arrays(draw) -> SampleArrays:  # type: ignore[no-untyped-def]
    n = draw(st.integers(1, 30))
    names = [ch.name for ch in (*SENSOR, *TRUTH)]
    columns = {k: draw(hnp.arrays(np.float64, n, elements=FINITE)) for k in names}
    return _samples(columns, draw(st.booleans()))


def test_the_lateral_channels_are_the_ones_that_change_sign_in_a_mirror() -> None:
    assert set(LATERAL_CHANNELS) == {
        "y_v_mps",
        "y_a_mps2",
        "yaw_rate_radps",
        "stl_m",
        "stl_rate_mps",
        "truth_v_y_mps",
        "truth_yaw_rate_radps",
    }


@settings(max_examples=60, deadline=None)
@given(sample_arrays())
def test_mirroring_twice_gives_the_samples_back_and_negates_only_lateral_columns(s) -> None:
    m = mirrored(s)
    back = mirrored(m)
    for f in dataclasses.fields(s):
        a, b, c = getattr(s, f.name), getattr(m, f.name), getattr(back, f.name)
        if a is None:
            assert b is None and c is None
            continue
        np.testing.assert_array_equal(c, a, err_msg=f.name)
        np.testing.assert_array_equal(b, -a if f.name in LATERAL_CHANNELS else a, f.name)
    if s.has_truth:
        np.testing.assert_array_equal(m.beta_rad(), -s.beta_rad())


def test_a_mirrored_run_is_the_simulators_answer_to_the_mirrored_steering() -> None:
    from sideslip_sim.maneuvers import Maneuver
    from sideslip_sim.sensors import exact_samples
    from sideslip_sim.simulate import simulate
    from sideslip_sim.vehicle import load_vehicle

    car = load_vehicle("paper_sedan")
    kw = {"duration_s": 2.0, "speed_kmh": 70.0, "torque_nm": 150.0, "mu": 0.6}
    left = exact_samples(simulate(car, Maneuver("l", "sine_steer", stl_amplitude_m=0.03, **kw)))
    right = exact_samples(simulate(car, Maneuver("r", "sine_steer", stl_amplitude_m=-0.03, **kw)))
    m = mirrored(left)
    assert np.max(np.abs(left.beta_rad())) > 0.005  # the run does slip
    for f in dataclasses.fields(m):
        np.testing.assert_allclose(
            getattr(m, f.name), getattr(right, f.name), rtol=1e-6, atol=1e-9, err_msg=f.name
        )
