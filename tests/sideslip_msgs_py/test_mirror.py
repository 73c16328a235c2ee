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


@settings(max_examples=40, deadline=None)
@given(
    rows=hnp.arrays(np.float64, (5, 9), elements=st.floats(-50.0, 50.0, allow_nan=False, width=64)),
)
def test_every_model_input_is_negated_or_kept_by_a_mirror_as_input_signs_declares(rows) -> None:
    """Each channel, derived and conditioning input, computed from mirrored channels,
    equals its sign times the input of the run as driven: the estimator's mirror average
    relies on it for every input it may read."""
    from sideslip_msgs_py.features import CHANNELS
    from sideslip_msgs_py.mirror import ODD_INPUTS, input_signs
    from sideslip_msgs_py.model_inputs import (
        CONDITIONING,
        DERIVED,
        OBSERVER_COLUMNS,
        input_matrix,
    )
    from sideslip_msgs_py.vehicle_description import VehicleDescription

    names = (*CHANNELS, *DERIVED, *CONDITIONING, *OBSERVER_COLUMNS)
    columns = {c: rows[:, j % rows.shape[1]] for j, c in enumerate(CHANNELS)}
    columns["x_v_mps"] = np.abs(columns["x_v_mps"]) + 2.0  # forward speed keeps its sign
    for j, c in enumerate(OBSERVER_COLUMNS):
        columns[c] = rows[:, (j + 3) % rows.shape[1]]
    columns["ukf.road_friction"] = np.abs(columns["ukf.road_friction"])
    # The observer columns as the filter gives them for the mirrored run: that it does
    # is checked against the filter itself (tests/sideslip_estimator/test_mirror_average.py).
    flipped = {c: -v if c in LATERAL_CHANNELS or c in ODD_INPUTS else v for c, v in columns.items()}
    car = VehicleDescription(1500.0, 2.7, 1.2, 0.55, 1.55, 1.6, 0.31)
    plain = input_matrix(columns, names, car)
    mirror = input_matrix(flipped, names, car)
    np.testing.assert_array_equal(mirror, plain * input_signs(names))
