"""Model inputs and priors: the window and the whole-run computations agree, the
kinematic prior is exact on exact data, mirrored driving mirrors them, and a vehicle
description reads from a file or from simulator parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py import model_inputs as mi
from sideslip_msgs_py.features import CHANNELS
from sideslip_msgs_py.mirror import LATERAL_CHANNELS
from sideslip_msgs_py.vehicle_description import VehicleDescription, VehicleDescriptionError

DT = 0.0025
CAR = VehicleDescription(1500.0, 2.7, 1.2, 0.55, 1.55, 1.6, 0.32)
ODD = LATERAL_CHANNELS  # change sign when mirrored


def _columns(n: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    return {
        "x_v_mps": 20.0 + 2.0 * np.sin(0.7 * t) + rng.normal(0, 0.3, n),
        "y_v_mps": 0.4 * np.sin(1.3 * t) + rng.normal(0, 0.3, n),
        "x_a_mps2": 1.4 * np.cos(0.7 * t) + rng.normal(0, 0.1, n),
        "y_a_mps2": 3.0 * np.sin(1.1 * t) + rng.normal(0, 0.1, n),
        "yaw_rate_radps": 0.15 * np.sin(1.1 * t) + rng.normal(0, 0.003, n),
        "stl_m": 0.05 * np.sin(1.1 * t),
        # What a UKF would report beside the channels (the caller's column).
        "ukf.beta_rad": 0.02 * np.sin(1.3 * t),
        "ukf.road_friction": 0.9 + 0.05 * np.sin(0.2 * t),
        "ukf.yaw_rate_innovation_radps": rng.normal(0, 0.003, n),
        "ukf.lateral_acceleration_innovation_mps2": rng.normal(0, 0.2, n),
    }


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from(sorted(mi.PRIORS)))
def test_prior_of_a_window_equals_the_run_series_at_its_last_sample(seed, prior):
    n, window = 400, 100
    cols = _columns(n, seed)
    series = mi.prior_series(cols, prior, window, DT)
    for end in (window - 1, 250, n - 1):
        rows = {c: v[end - window + 1 : end + 1] for c, v in cols.items()}
        assert mi.prior_of_window(rows, prior, DT) == pytest.approx(series[end], abs=1e-12)


def test_kinematic_window_prior_is_exact_when_the_rates_are():
    # v_y = 0.5 + 0.8·t with a_y − u·ψ̇ = 0.8 exactly, v_x constant: the dead-reckoned
    # mean of noiseless samples is the true final velocity (to rectangle-rule error 0).
    n = 100
    t = np.arange(n) * DT
    u, r = 25.0, 0.1
    cols = {
        "x_v_mps": np.full(n, u),
        "y_v_mps": 0.5 + 0.8 * t,
        "x_a_mps2": np.zeros(n),
        "y_a_mps2": np.full(n, 0.8 + u * r),
        "yaw_rate_radps": np.full(n, r),
    }
    assert mi.prior_of_window(cols, "kinematic_window", DT) == pytest.approx(
        math.atan2(0.5 + 0.8 * t[-1], u), abs=1e-12
    )


def test_kinematic_window_prior_averages_measurement_noise_down():
    rng = np.random.default_rng(1)
    n, u = 100, 20.0
    errors = []
    for _ in range(200):
        cols = {
            "x_v_mps": u + rng.normal(0, 0.28, n),
            "y_v_mps": 0.3 + rng.normal(0, 0.28, n),
            "x_a_mps2": np.zeros(n),
            "y_a_mps2": np.zeros(n),
            "yaw_rate_radps": np.zeros(n),
        }
        errors.append(mi.prior_of_window(cols, "kinematic_window", DT) - math.atan2(0.3, u))
    raw = 0.28 / u  # one sample's error in β [rad]
    assert np.std(errors) < 0.15 * raw  # ~1/√100 of one sample's


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 10_000))
def test_mirrored_driving_mirrors_every_derived_input_and_the_prior(seed):
    cols = _columns(200, seed)
    mirrored = {c: (-v if c in ODD else v) for c, v in cols.items()}
    names = tuple(mi.DERIVED)
    a = mi.input_matrix(cols, names, CAR)
    b = mi.input_matrix(mirrored, names, CAR)
    even = {"x_a_g"}
    for j, name in enumerate(names):
        expected = a[:, j] if name in even else -a[:, j]
        np.testing.assert_allclose(b[:, j], expected, atol=1e-15, err_msg=name)
    p = mi.prior_series(cols, "kinematic_window", 100, DT)
    q = mi.prior_series(mirrored, "kinematic_window", 100, DT)
    np.testing.assert_allclose(q[99:], -p[99:], atol=1e-15)


def test_scaled_inputs_have_the_units_they_name():
    cols = _columns(50, 3)
    x = mi.input_matrix(cols, ("y_a_g", "road_wheel_angle_rad", "vehicle.mass_kg"), CAR)
    np.testing.assert_allclose(x[:, 0], cols["y_a_mps2"] / 9.80665)
    np.testing.assert_allclose(x[:, 1], cols["stl_m"] / 1.6)
    assert np.all(x[:, 2] == 1500.0)


def test_inputs_that_read_the_car_refuse_to_run_without_one():
    assert mi.needs_vehicle(("road_wheel_angle_rad",))
    assert not mi.needs_vehicle(mi.INPUT_SETS["paper_kinematic"], "kinematic_window")
    with pytest.raises(mi.ModelInputError, match="nominal parameters"):
        mi.input_matrix(_columns(10, 0), ("vehicle.mass_kg",), None)


def test_observer_inputs_and_prior_read_the_callers_columns():
    cols = _columns(150, 4)
    names = mi.INPUT_SETS["measurable_observer"]
    assert mi.needs_observer(names) and mi.needs_observer(("x_v_mps",), "ukf")
    assert not mi.needs_observer(mi.INPUT_SETS["measurable_invariant"], "none")
    # The filter reads the car from its own params file, not the model's description.
    assert not mi.needs_vehicle(("x_v_mps", "ukf.beta_rad"), "ukf")
    assert "y_v_mps" not in mi.required_channels(names, "ukf")
    x = mi.input_matrix(cols, names, CAR)
    np.testing.assert_array_equal(x[:, names.index("ukf.beta_rad")], cols["ukf.beta_rad"])
    prior = mi.prior_series(cols, "ukf", 100, DT)
    assert np.isnan(prior[:99]).all()
    np.testing.assert_array_equal(prior[99:], cols["ukf.beta_rad"][99:])
    del cols["ukf.beta_rad"]
    with pytest.raises(mi.ModelInputError, match=r"ukf\.beta_rad is the UKF observer's output"):
        mi.input_matrix(cols, names, CAR)
    with pytest.raises(mi.ModelInputError, match="UKF observer"):
        mi.prior_series(cols, "ukf", 100, DT)


def test_unknown_inputs_and_priors_are_refused_naming_them():
    with pytest.raises(mi.ModelInputError, match=r"\['speed'\]"):
        mi.check_inputs(("x_v_mps", "speed"))
    with pytest.raises(mi.ModelInputError, match="unknown prior 'magic'"):
        mi.check_prior("magic")


def test_required_channels_cover_inputs_and_prior_in_contract_order():
    assert mi.required_channels(("y_a_g",), "none") == ("y_a_mps2",)
    assert mi.required_channels(("x_v_mps",), "kinematic_window") == CHANNELS[:5]
    measurable = mi.required_channels(mi.INPUT_SETS["measurable_invariant"])
    assert "y_v_mps" not in measurable


def test_vehicle_description_reads_a_file_and_simulator_parameters(tmp_path):
    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump(CAR.to_dict() | {"name": "mine"}))
    assert VehicleDescription.load(path) == CAR
    sim = {
        "sprung_mass_kg": 1400.0, "unsprung_mass_front_kg": 30.0, "unsprung_mass_rear_kg": 20.0,
        "cg_to_front_axle_m": 1.2, "cg_to_rear_axle_m": 1.5, "cg_height_m": 0.55,
        "track_front_m": 1.5, "track_rear_m": 1.6, "stl_per_road_wheel_angle_m_per_rad": 1.6,
        "tire_rolling_radius_m": 0.32, "drag_coefficient": 0.3,
    }  # fmt: skip
    desc = VehicleDescription.from_mapping(sim)
    assert desc.mass_kg == 1500.0 and desc.wheelbase_m == pytest.approx(2.7)
    assert desc.front_weight_fraction == pytest.approx(1.5 / 2.7)
    assert desc.track_m == pytest.approx(1.55)


def test_a_bad_vehicle_description_names_the_file_and_key(tmp_path):
    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump({"mass_kg": 1500.0}))
    with pytest.raises(VehicleDescriptionError, match=r"car\.yaml.*missing key\(s\).*wheelbase_m"):
        VehicleDescription.load(path)
    bad = CAR.to_dict() | {"cg_to_front_axle_m": 3.0}
    with pytest.raises(VehicleDescriptionError, match="between the axles"):
        VehicleDescription.from_mapping(bad)
