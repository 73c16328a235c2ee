"""Estimator back-ends: the registry, the kinematic baseline and the single-track observer
(accuracy against the 14-DOF simulator, parameter files and their refusals)."""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_estimator.backends import (
    BACKENDS,
    BackendError,
    SingleTrackParams,
    backend_factory,
    create_backend,
)
from sideslip_estimator.backends.kinematic import KinematicBackend
from sideslip_estimator.backends.pso_lstm import PsoLstmBackend
from sideslip_estimator.backends.single_track import SingleTrackBackend
from sideslip_estimator.backends.ukf import UkfBackend
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_msgs_py.features import CHANNELS
from sideslip_msgs_py.messages import ImuFields, SteeringFields, TwistFields
from sideslip_msgs_py.sample import SampleArrays
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.sensors import exact_samples
from sideslip_sim.simulate import simulate
from sideslip_sim.single_track import estimator_parameters
from sideslip_sim.tire import load_tire
from sideslip_sim.vehicle import load_vehicle, shipped_vehicles

STEP_NS = 2_500_000
X_V, Y_V = CHANNELS.index("x_v_mps"), CHANNELS.index("y_v_mps")
SHIPPED = resources.files("sideslip_estimator").joinpath("data/single_track")


def _rows(x_v: list[float], y_v: list[float]) -> tuple[np.ndarray, np.ndarray]:
    rows = np.zeros((len(x_v), len(CHANNELS)))
    rows[:, X_V], rows[:, Y_V] = x_v, y_v
    return rows, np.arange(len(x_v), dtype=np.int64) * STEP_NS


# --- registry -------------------------------------------------------------------------------------


def test_registry_holds_every_backend() -> None:
    assert BACKENDS == {
        "kinematic": KinematicBackend,
        "single_track": SingleTrackBackend,
        "pso_lstm": PsoLstmBackend,
        "ukf": UkfBackend,
    }
    for name, factory in BACKENDS.items():
        assert factory.name == name
        assert backend_factory(name) is factory


def test_unknown_backend_is_an_error_listing_the_known_ones() -> None:
    with pytest.raises(
        BackendError, match=r"'transformer'.*kinematic, single_track, pso_lstm, ukf"
    ):
        create_backend("transformer", {}, 100)


def test_every_backend_builds_from_its_declared_defaults() -> None:
    # pso_lstm's default is the shipped PSO-LSTM, so this also proves it is shipped.
    for name, factory in BACKENDS.items():
        values = {p.name: p.default for p in factory.parameters}
        backend = create_backend(name, values, 100)
        assert backend.name == name and backend.model_id.startswith(name)


# --- kinematic ------------------------------------------------------------------------------------


def test_raw_kinematic_is_atan2_of_the_newest_row_exactly() -> None:
    backend = create_backend("kinematic", {"smoothing_steps": 1}, 100)
    rows, stamps = _rows([10.0, 20.0, 13.7], [3.0, -1.0, 0.9])
    est = backend.update(rows, stamps)
    assert est is not None and est.beta_rad == math.atan2(0.9, 13.7)
    assert backend.model_id == "kinematic(smoothing_steps=1)"


def test_smoothing_averages_the_last_n_velocity_components_before_atan2() -> None:
    backend = create_backend("kinematic", {"smoothing_steps": 3}, 100)
    rows, stamps = _rows([50.0, 10.0, 20.0, 30.0], [50.0, 1.0, -2.0, 7.0])
    est = backend.update(rows, stamps)
    assert est is not None
    assert est.beta_rad == pytest.approx(math.atan2(2.0, 20.0), abs=1e-15)
    # Fewer rows than smoothing_steps (window still filling): all rows averaged.
    est = backend.update(rows[:2], stamps[:2])
    assert est is not None and est.beta_rad == pytest.approx(math.atan2(25.5, 30.0), abs=1e-15)


def test_averaging_components_not_angles() -> None:
    # atan2 of the mean velocity, not the mean of the two angles (which would be 0).
    backend = create_backend("kinematic", {"smoothing_steps": 2}, 100)
    est = backend.update(*_rows([10.0, 30.0], [10.0, -10.0]))
    assert est is not None and est.beta_rad == 0.0
    est = backend.update(*_rows([10.0, 30.0], [10.0, 0.0]))
    assert est is not None and est.beta_rad == pytest.approx(math.atan2(5.0, 20.0))
    assert est.beta_rad != pytest.approx((math.pi / 4) / 2)


def test_kinematic_variance_is_sigma_squared_over_n_speed_squared() -> None:
    backend = create_backend("kinematic", {"smoothing_steps": 4, "velocity_sigma_mps": 0.3}, 100)
    est = backend.update(*_rows([20.0] * 4, [0.0] * 4))
    assert est is not None and est.variance_rad2 == pytest.approx(0.09 / (4 * 400.0))


def test_kinematic_gives_no_estimate_for_zero_velocity() -> None:
    backend = create_backend("kinematic", {}, 100)
    assert backend.update(*_rows([0.0], [0.0])) is None


@settings(max_examples=200, deadline=None)
@given(
    n=st.integers(1, 20),
    data=st.lists(
        st.tuples(st.floats(-100.0, 100.0), st.floats(-100.0, 100.0)), min_size=1, max_size=25
    ),
)
def test_kinematic_mirror_symmetry_negated_y_v_gives_negated_beta(
    n: int, data: list[tuple[float, float]]
) -> None:
    backend = create_backend("kinematic", {"smoothing_steps": n}, 20)
    x_v = [d[0] for d in data]
    y_v = [d[1] for d in data]
    est = backend.update(*_rows(x_v, y_v))
    mirrored = backend.update(*_rows(x_v, [-y for y in y_v]))
    if est is None:
        assert mirrored is None
        return
    assert mirrored is not None
    assert mirrored.beta_rad == -est.beta_rad or (
        abs(est.beta_rad) == math.pi and abs(mirrored.beta_rad) == math.pi  # ±π: same angle
    )
    assert mirrored.variance_rad2 == est.variance_rad2


@pytest.mark.parametrize("steps", [0, -1, 101, 2.5])
def test_bad_smoothing_steps_is_a_backend_error_naming_the_parameter(steps: object) -> None:
    # 2.5 must not be truncated to 2 silently.
    with pytest.raises(BackendError, match="smoothing_steps"):
        create_backend("kinematic", {"smoothing_steps": steps}, 100)


@pytest.mark.parametrize("sigma", [-0.1, math.nan, math.inf])
def test_bad_velocity_sigma_is_a_backend_error_naming_the_parameter(sigma: object) -> None:
    with pytest.raises(BackendError, match="velocity_sigma_mps"):
        create_backend("kinematic", {"velocity_sigma_mps": sigma}, 100)


def test_smoothing_up_to_the_window_length_is_accepted() -> None:
    assert create_backend("kinematic", {"smoothing_steps": 100}, 100).model_id.endswith("=100)")


# --- single-track observer: accuracy on the full vehicle model ------------------------------


def _observer_beta(samples: SampleArrays, params_file: str = "paper_sedan") -> np.ndarray:
    """β̂ per sample (NaN where none) from the estimator with the single_track back-end."""
    est = Estimator(
        create_backend("single_track", {"params_file": params_file}, 100), EstimatorParams()
    )
    beta = np.full(len(samples), np.nan)
    s = samples
    for i in range(len(s)):
        stamp = int(s.stamp_ns[i])
        est.on_twist("/t", TwistFields(stamp, float(s.x_v_mps[i]), float(s.y_v_mps[i])))
        est.on_steering("/s", SteeringFields(stamp, float(s.stl_m[i]), float(s.stl_rate_mps[i])))
        imu = ImuFields(
            stamp, float(s.x_a_mps2[i]), float(s.y_a_mps2[i]), float(s.yaw_rate_radps[i])
        )
        out = est.on_imu("/i", imu)
        if out is not None:
            beta[i] = out.estimate.beta_rad
    return beta


# Noise-free 6-s runs at 90 km/h, |a_y| <= 4 m/s² (the tyres' linear range). Measured
# on paper_sedan after 1 s: max |error| 0.066° (step) and 0.082° (sine), mean 0.06°
# and 0.05°, with |β| up to 0.9-1.0°: the tolerances leave margin for numerical drift,
# not for a wrong model (a zero or sign-flipped estimate fails them).
ACCURACY_RUNS = {
    "step": Maneuver("st_step", "step_steer", 6.0, 90.0, 300.0, ay_fraction=0.38),
    "sine": Maneuver("st_sine", "sine_steer", 6.0, 90.0, 300.0, ay_fraction=0.38),
}
MAX_ERROR_DEG = 0.2
MEAN_ERROR_DEG = 0.12
CONVERGED_S = 1.0


@pytest.fixture(scope="module", params=sorted(ACCURACY_RUNS))
def linear_range_run(request: pytest.FixtureRequest) -> SampleArrays:
    result = simulate(load_vehicle("paper_sedan"), ACCURACY_RUNS[request.param])
    assert np.max(np.abs(result.ay_mps2)) <= 4.0  # the premise of the test
    return exact_samples(result, start_stamp_ns=10**18)


def test_single_track_observer_tracks_beta_of_the_full_model_in_the_linear_range(
    linear_range_run: SampleArrays,
) -> None:
    truth = linear_range_run.beta_rad()
    beta = _observer_beta(linear_range_run)
    assert np.all(np.isnan(beta[:99])) and np.all(np.isfinite(beta[99:]))
    settled = slice(round(CONVERGED_S * 400), None)
    err_deg = np.degrees(beta[settled] - truth[settled])
    assert np.max(np.abs(np.degrees(truth))) > 3 * MAX_ERROR_DEG  # the test discriminates
    assert np.max(np.abs(err_deg)) <= MAX_ERROR_DEG
    assert np.mean(np.abs(err_deg)) <= MEAN_ERROR_DEG


def test_single_track_mirrored_inputs_give_exactly_mirrored_beta() -> None:
    rng = np.random.default_rng(3)
    n = 400
    rows = np.zeros((n, len(CHANNELS)))
    rows[:, CHANNELS.index("x_v_mps")] = 20.0 + rng.normal(0, 0.3, n)
    for name, scale in (("y_v_mps", 0.5), ("y_a_mps2", 3.0), ("yaw_rate_radps", 0.2),
                        ("stl_m", 0.02), ("x_a_mps2", 0.3)):  # fmt: skip
        rows[:, CHANNELS.index(name)] = rng.normal(0, scale, n)
    mirror = rows.copy()
    for name in ("y_v_mps", "y_a_mps2", "yaw_rate_radps", "stl_m"):
        mirror[:, CHANNELS.index(name)] *= -1.0
    stamps = np.arange(n, dtype=np.int64) * STEP_NS
    a = create_backend("single_track", {}, 100)
    b = create_backend("single_track", {}, 100)
    for k in range(1, n + 1):
        ea, eb = a.update(rows[:k], stamps[:k]), b.update(mirror[:k], stamps[:k])
        assert ea is not None and eb is not None
        assert eb.beta_rad == -ea.beta_rad and eb.variance_rad2 == ea.variance_rad2


def test_single_track_below_its_min_speed_gives_none_and_restarts() -> None:
    backend = create_backend("single_track", {"min_speed_mps": 2.0}, 100)
    rows = np.zeros((4, len(CHANNELS)))
    rows[:, X_V] = [20.0, 20.0, 1.5, 20.0]
    rows[:, CHANNELS.index("yaw_rate_radps")] = [0.3, 0.3, 0.0, 0.1]
    rows[:, CHANNELS.index("y_a_mps2")] = [6.0, 6.0, 0.0, 2.0]
    stamps = np.arange(4, dtype=np.int64) * STEP_NS
    assert backend.update(rows[:1], stamps[:1]) is not None
    assert backend.update(rows[:2], stamps[:2]) is not None
    assert backend.update(rows[:3], stamps[:3]) is None
    # The filter restarted from its prior: the next estimate is a fresh filter's first.
    fresh = create_backend("single_track", {"min_speed_mps": 2.0}, 100)
    assert backend.update(rows, stamps) == fresh.update(rows[3:], stamps[3:])


def test_single_track_reset_forgets_the_state() -> None:
    rows = np.zeros((1, len(CHANNELS)))
    rows[0, X_V], rows[0, CHANNELS.index("y_a_mps2")] = 20.0, 3.0
    stamps = np.zeros(1, dtype=np.int64)
    fresh = create_backend("single_track", {}, 100).update(rows, stamps)
    used = create_backend("single_track", {}, 100)
    for k in range(50):
        r = rows.copy()
        r[0, CHANNELS.index("yaw_rate_radps")] = 0.3
        used.update(r, stamps + k * STEP_NS)
    used.reset()
    again = used.update(rows, stamps)
    assert again == fresh


# --- single-track parameter files -----------------------------------------------------------------


def _shipped_names() -> list[str]:
    return sorted(p.name.removesuffix(".yaml") for p in SHIPPED.iterdir())


def test_a_single_track_file_is_shipped_for_every_shipped_vehicle() -> None:
    assert _shipped_names() == shipped_vehicles()


@pytest.mark.parametrize("vehicle", shipped_vehicles())
def test_shipped_single_track_yaml_equals_the_export_from_the_vehicle_file(vehicle: str) -> None:
    v = load_vehicle(vehicle)
    exported = estimator_parameters(v, load_tire(str(v.tire_path())))
    shipped = yaml.safe_load(SHIPPED.joinpath(f"{vehicle}.yaml").read_text())
    assert shipped == exported
    assert SingleTrackParams.load(vehicle) == SingleTrackParams.from_mapping(exported, "export")


def test_model_id_names_the_parameter_set() -> None:
    assert create_backend("single_track", {}, 100).model_id == "single_track(paper_sedan)"
    backend = create_backend("single_track", {"params_file": "compact_rwd"}, 100)
    assert backend.model_id == "single_track(compact_rwd)"


def test_unknown_params_file_name_lists_the_shipped_ones() -> None:
    with pytest.raises(BackendError) as info:
        create_backend("single_track", {"params_file": "hovercraft"}, 100)
    msg = str(info.value)
    assert "params_file" in msg and "hovercraft" in msg
    for name in _shipped_names():
        assert name in msg


def test_missing_params_yaml_path_is_an_error_naming_the_path(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.yaml"
    with pytest.raises(BackendError, match=r"params_file .*nowhere\.yaml: cannot read"):
        create_backend("single_track", {"params_file": str(path)}, 100)


def _good_mapping() -> dict[str, object]:
    return yaml.safe_load(SHIPPED.joinpath("paper_sedan.yaml").read_text())


def test_params_yaml_path_is_loaded(tmp_path: Path) -> None:
    data = _good_mapping() | {"name": "my_car", "mass_kg": 1500.0}
    path = tmp_path / "my_car.yaml"
    path.write_text(yaml.safe_dump(data))
    backend = create_backend("single_track", {"params_file": str(path)}, 100)
    assert backend.params.name == "my_car" and backend.params.mass_kg == 1500.0


@pytest.mark.parametrize(
    ("change", "match"),
    [({"tyre_model": "linear"}, r"unknown keys \['tyre_model'\]"),
     ({"mass_kg": None}, r"missing keys \['mass_kg'\]")],
)  # fmt: skip
def test_params_yaml_with_unknown_or_missing_keys_is_refused_naming_the_file(
    tmp_path: Path, change: dict[str, object], match: str
) -> None:
    data = _good_mapping() | change
    data = {k: v for k, v in data.items() if v is not None}
    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(BackendError, match=match) as info:
        create_backend("single_track", {"params_file": str(path)}, 100)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("bad", [0, -1500.0, "heavy", True, float("nan"), float("inf")])
def test_params_yaml_values_must_be_positive_finite_numbers(tmp_path: Path, bad: object) -> None:
    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump(_good_mapping() | {"mass_kg": bad}))
    with pytest.raises(BackendError, match="mass_kg"):
        create_backend("single_track", {"params_file": str(path)}, 100)


def test_params_yaml_that_is_not_a_mapping_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "list.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(BackendError, match="expected a mapping"):
        create_backend("single_track", {"params_file": str(path)}, 100)


@pytest.mark.parametrize(
    "key",
    ["yaw_rate_sigma_radps", "lateral_acceleration_sigma_mps2", "process_sigma_lateral_mps2",
     "process_sigma_yaw_radps2", "min_speed_mps"],
)  # fmt: skip
@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf])
def test_bad_single_track_tuning_is_a_backend_error_naming_the_parameter(
    key: str, bad: float
) -> None:
    with pytest.raises(BackendError, match=f"single_track.{key}"):
        create_backend("single_track", {key: bad}, 100)


@pytest.mark.parametrize(
    ("backend", "key"),
    [("kinematic", "smoothing_steps"), ("kinematic", "velocity_sigma_mps"),
     ("single_track", "yaw_rate_sigma_radps")],
)  # fmt: skip
def test_non_numeric_backend_value_is_a_backend_error_naming_the_parameter(
    backend: str, key: str
) -> None:
    # The node declares typed parameters, but create_backend is also the API of scripts
    # (bench, evaluation): their mistakes deserve the same one-line error.
    with pytest.raises(BackendError, match=f"{backend}.{key}"):
        create_backend(backend, {key: "lots"}, 100)
