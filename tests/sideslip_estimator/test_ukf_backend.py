"""The ``ukf`` back-end: the linear single-track model in the tyres' linear range, accuracy
against the 14-DOF simulator (dry and low friction), its parameter files and refusals,
mirror symmetry, and that it never publishes NaN."""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sideslip_estimator.backends import BackendError, UkfParams, create_backend
from sideslip_estimator.backends.ukf import MAX_GAP_S, UkfBackend
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_msgs_py.features import CHANNELS
from sideslip_msgs_py.messages import ImuFields, SteeringFields, TwistFields
from sideslip_msgs_py.sample import SampleArrays
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.sensors import add_noise, exact_samples, noise_profile
from sideslip_sim.simulate import simulate
from sideslip_sim.vehicle import load_vehicle

DEFAULTS = {p.name: p.default for p in UkfBackend.parameters}

STEP_NS = 2_500_000
DT_S = 2.5e-3
COL = {name: i for i, name in enumerate(CHANNELS)}
SHIPPED = resources.files("sideslip_estimator").joinpath("data/ukf")


def _feed(backend: UkfBackend, rows: np.ndarray, stamps: np.ndarray) -> list:
    """Every row through the back-end as the runtime does (newest row last)."""
    return [backend.update(rows[: k + 1], stamps[: k + 1]) for k in range(len(rows))]


# --- linear range: the UKF is the linear single-track model -----------------------------


def _linear_single_track_run(
    p: UkfParams, relaxation: bool, speed_mps: float, delta_amp_rad: float, seconds: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The linear bicycle model (axle stiffness B·C·D of the file, optionally with the
    tyres' first-order lag) under a 0.5-Hz sine steer at constant speed: RK4 at 1/20 of
    the sample period. Returns (rows in CHANNELS order, stamps, β [rad]) per sample."""
    m, iz = p.mass_kg, p.yaw_inertia_kgm2
    a, b = p.cg_to_front_axle_m, p.cg_to_rear_axle_m
    g = 9.80665
    cf = p.mf_b_front * p.mf_c_front * p.mu_peak_front * m * g * b / (a + b)
    cr = p.mf_b_rear * p.mf_c_rear * p.mu_peak_rear * m * g * a / (a + b)
    u = speed_mps

    def delta(t: float) -> float:
        return delta_amp_rad * math.sin(2.0 * math.pi * 0.5 * t)

    def forces(x: np.ndarray, t: float) -> tuple[float, float]:
        if relaxation:
            return cf * x[2], cr * x[3]
        v_y, r = x[0], x[1]
        return cf * (delta(t) - (v_y + a * r) / u), cr * (-(v_y - b * r) / u)

    def f(x: np.ndarray, t: float) -> np.ndarray:
        v_y, r = x[0], x[1]
        ff, fr = forces(x, t)
        dx = [(ff + fr) / m - u * r, (a * ff - b * fr) / iz]
        if relaxation:
            dx.append(u / p.relaxation_length_front_m * (delta(t) - (v_y + a * r) / u - x[2]))
            dx.append(u / p.relaxation_length_rear_m * (-(v_y - b * r) / u - x[3]))
        return np.array(dx)

    n, sub = round(seconds / DT_S), 20
    h = DT_S / sub
    x = np.zeros(4 if relaxation else 2)
    rows = np.zeros((n, len(CHANNELS)))
    beta = np.zeros(n)
    for k in range(n):
        t = k * DT_S
        ff, fr = forces(x, t)
        rows[k, COL["x_v_mps"]] = u
        rows[k, COL["yaw_rate_radps"]] = x[1]
        rows[k, COL["y_a_mps2"]] = (ff + fr) / m
        # X_a is v̇_x − ψ̇ v_y: constant speed means a_x = −ψ̇ v_y.
        rows[k, COL["x_a_mps2"]] = -x[1] * x[0]
        rows[k, COL["stl_m"]] = delta(t) * p.stl_per_road_wheel_angle_m_per_rad
        beta[k] = math.atan2(x[0], u)
        for i in range(sub):
            tt = t + i * h
            k1 = f(x, tt)
            k2 = f(x + 0.5 * h * k1, tt + 0.5 * h)
            k3 = f(x + 0.5 * h * k2, tt + 0.5 * h)
            k4 = f(x + h * k3, tt + h)
            x = x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return rows, np.arange(n, dtype=np.int64) * STEP_NS, beta


# Sine steer at 90 km/h with |a_y| ≈ 0.8 m/s² (the tyres' linear range, |α| < 0.3°), no
# noise, μ known (no friction state). Measured: max |β̂ − β| 0.0004° (|β| up to 0.24°),
# 0.2 % of the peak; the bound is 1 %. 5 % less front cornering stiffness in the file gives
# 5.8 % (next test), so the bound checks the model, not only the filter's tracking.
LINEAR_BOUND = 0.01


def _linear_range_error(values: dict, relaxation: bool = True) -> tuple[float, UkfBackend]:
    """max |β̂ − β| / max |β| of the UKF on the linear model's sine steer."""
    p = UkfParams.load("paper_sedan")
    rows, stamps, truth = _linear_single_track_run(p, relaxation, 25.0, 0.0065, 4.0)
    assert 0.7 < np.max(np.abs(rows[:, COL["y_a_mps2"]])) < 1.3  # the premise: a_y ≈ 1
    backend = create_backend("ukf", {"tyre_relaxation": relaxation, **values}, 100)
    beta = np.array([e.beta_rad for e in _feed(backend, rows, stamps)])
    return float(np.max(np.abs(beta - truth)) / np.max(np.abs(truth))), backend


@pytest.mark.parametrize("relaxation", [True, False], ids=["relaxed tyres", "instant tyres"])
def test_ukf_in_the_linear_range_gives_the_linear_single_track_beta(relaxation: bool) -> None:
    error, _ = _linear_range_error({"estimate_friction": False}, relaxation)
    assert error <= LINEAR_BOUND


def test_linear_range_bound_discriminates_a_wrong_cornering_stiffness(tmp_path: Path) -> None:
    data = yaml.safe_load(SHIPPED.joinpath("paper_sedan.yaml").read_text())
    data["mu_peak_front"] *= 0.95  # D, so B·C·D, 5 % lower
    path = tmp_path / "softer.yaml"
    path.write_text(yaml.safe_dump(data))
    error, _ = _linear_range_error({"estimate_friction": False, "params_file": str(path)})
    assert error > LINEAR_BOUND


def test_friction_state_stays_near_its_start_and_beta_near_the_linear_model() -> None:
    # With the defaults μ is estimated. In the linear range it is hardly observable (the
    # cornering stiffness does not depend on it): it wanders a little on the model's tiny
    # nonlinearity. Measured: μ 1.045, β within 3.0 % of the peak.
    error, backend = _linear_range_error({})
    assert error <= 0.05
    assert backend.state["road_friction"] == pytest.approx(1.0, abs=0.1)


# --- the full vehicle model -------------------------------------------------------------


def _beta_through_estimator(samples: SampleArrays, backend: str, values: dict) -> np.ndarray:
    est = Estimator(create_backend(backend, values, 100), EstimatorParams())
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


# 6-s runs on paper_sedan with the paper's sensor noise (seeded), into the tyres' nonlinear
# range: a sine steer on a dry road at 0.85 of the μ-limited a_y (6 m/s², β up to 2°),
# and a step steer on μ = 0.4 (which the UKF is not told) at 0.8 of it. Measured MAE after
# 1 s [deg], ukf / single_track, with the noise defaults tuned on the fleet (2026-12-03):
# dry 0.018 / 0.242, low μ 0.104 / 0.283 (with the earlier defaults, tuned on paper_sedan:
# 0.037 and 0.047). This one unannounced low-μ step steer on paper_sedan got worse; on the
# μ 0.4 step steers of 16 validation-fleet cars the tuned defaults are better (0.062° →
# 0.056°; docs/training.md, "The UKF's noise on the fleet"). The bounds: about twice the
# UKF's error, and well under the linear observer's.
FULL_MODEL_RUNS = {
    "dry": Maneuver("ukf_dry", "sine_steer", 6.0, 80.0, 300.0, ay_fraction=0.85),
    "low_mu": Maneuver("ukf_low_mu", "step_steer", 6.0, 70.0, 150.0, mu=0.4, ay_fraction=0.8),
}
MAX_MAE_DEG = {"dry": 0.04, "low_mu": 0.2}
MAX_SHARE_OF_LINEAR = {"dry": 0.2, "low_mu": 0.5}


@pytest.mark.parametrize("run", sorted(FULL_MODEL_RUNS))
def test_ukf_beats_the_linear_observer_on_the_full_model_in_the_nonlinear_range(run: str) -> None:
    exact = exact_samples(simulate(load_vehicle("paper_sedan"), FULL_MODEL_RUNS[run]), 10**18)
    samples = add_noise(exact, noise_profile("paper"), 7)
    truth = samples.beta_rad()
    settled = slice(400, None)
    mae = {}
    for backend in ("ukf", "single_track"):
        beta = _beta_through_estimator(samples, backend, {})
        assert np.all(np.isfinite(beta[99:]))
        mae[backend] = float(np.mean(np.abs(np.degrees(beta - truth)[settled])))
    assert np.max(np.abs(np.degrees(truth))) > 0.5  # large enough for the bounds to mean much
    assert mae["ukf"] <= MAX_MAE_DEG[run]
    assert mae["ukf"] <= MAX_SHARE_OF_LINEAR[run] * mae["single_track"]


# --- parameter files --------------------------------------------------------------------


def _good_mapping() -> dict[str, object]:
    return yaml.safe_load(SHIPPED.joinpath("paper_sedan.yaml").read_text())


def test_model_id_names_the_parameter_set() -> None:
    assert create_backend("ukf", {}, 100).model_id == "ukf(paper_sedan)"
    assert create_backend("ukf", {"params_file": "compact_rwd"}, 100).model_id == (
        "ukf(compact_rwd)"
    )


def test_params_yaml_path_is_loaded(tmp_path: Path) -> None:
    path = tmp_path / "my_car.yaml"
    path.write_text(yaml.safe_dump(_good_mapping() | {"name": "my_car", "mass_kg": 1500.0}))
    backend = create_backend("ukf", {"params_file": str(path)}, 100)
    assert backend.params.name == "my_car" and backend.params.mass_kg == 1500.0


def test_unknown_shipped_params_name_lists_the_shipped_ones() -> None:
    with pytest.raises(BackendError, match=r"ukf\.params_file.*'hovercraft'") as info:
        create_backend("ukf", {"params_file": "hovercraft"}, 100)
    assert "paper_sedan" in str(info.value) and "compact_rwd" in str(info.value)


def test_missing_params_yaml_path_is_an_error_naming_the_path(tmp_path: Path) -> None:
    with pytest.raises(BackendError, match=r"ukf\.params_file .*nowhere\.yaml: cannot read"):
        create_backend("ukf", {"params_file": str(tmp_path / "nowhere.yaml")}, 100)


@pytest.mark.parametrize(
    ("change", "match"),
    [({"tyre_model": "pacejka"}, r"unknown keys \['tyre_model'\]"),
     ({"mf_b_rear": None}, r"missing keys \['mf_b_rear'\]"),
     ({"relaxation_length_front_m": None}, r"missing keys \['relaxation_length_front_m'\]")],
)  # fmt: skip
def test_params_yaml_with_unknown_or_missing_keys_is_refused_naming_the_file(
    tmp_path: Path, change: dict[str, object], match: str
) -> None:
    data = {k: v for k, v in (_good_mapping() | change).items() if v is not None}
    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(BackendError, match=match) as info:
        create_backend("ukf", {"params_file": str(path)}, 100)
    assert str(path) in str(info.value)


@pytest.mark.parametrize(
    ("key", "bad"),
    [("mass_kg", 0), ("mass_kg", -1.0), ("mass_kg", "heavy"), ("mass_kg", True),
     ("cg_height_m", float("nan")), ("mf_b_front", float("inf")), ("mu_peak_rear", 0.0),
     ("mf_c_front", 2.5), ("mf_c_rear", 0.0), ("mf_e_front", 1.2),
     ("relaxation_length_rear_m", -0.1)],
)  # fmt: skip
def test_params_yaml_values_out_of_range_are_refused_naming_file_and_key(
    tmp_path: Path, key: str, bad: object
) -> None:
    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump(_good_mapping() | {key: bad}))
    with pytest.raises(BackendError, match=key) as info:
        create_backend("ukf", {"params_file": str(path)}, 100)
    assert str(path) in str(info.value)


def test_negative_curvature_factor_e_is_accepted(tmp_path: Path) -> None:
    # MF 5.2 allows any E <= 1; the shipped fits have E < 0.
    assert _good_mapping()["mf_e_front"] < 0
    assert UkfParams.from_mapping(_good_mapping() | {"mf_e_rear": -3.0}, "x").mf_e_rear == -3.0


@pytest.mark.parametrize("text", ["- 1\n- 2\n", "mass_kg: [1,\n"], ids=["list", "bad yaml"])
def test_params_file_that_is_not_a_yaml_mapping_is_refused(tmp_path: Path, text: str) -> None:
    path = tmp_path / "car.yaml"
    path.write_text(text)
    with pytest.raises(BackendError, match=r"expected a mapping|not valid YAML") as info:
        create_backend("ukf", {"params_file": str(path)}, 100)
    assert str(path) in str(info.value)


@pytest.mark.parametrize(
    "key",
    ["yaw_rate_sigma_radps", "lateral_acceleration_sigma_mps2", "process_sigma_lateral_mps2",
     "process_sigma_friction_per_sqrt_s", "friction_initial", "min_speed_mps"],
)  # fmt: skip
@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf])
def test_bad_ukf_tuning_is_a_backend_error_naming_the_parameter(key: str, bad: float) -> None:
    with pytest.raises(BackendError, match=f"ukf.{key}"):
        create_backend("ukf", {key: bad}, 100)


def test_non_boolean_switch_is_a_backend_error_naming_it() -> None:
    with pytest.raises(BackendError, match=r"ukf\.estimate_friction"):
        create_backend("ukf", {"estimate_friction": 1}, 100)


# --- symmetry, robustness, restarts ------------------------------------------------------


def _random_drive(seed: int, n: int, speed: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """Plausible but inconsistent noisy channels (not physics): exercises the filter."""
    rng = np.random.default_rng(seed)
    rows = np.zeros((n, len(CHANNELS)))
    t = np.arange(n) * DT_S
    rows[:, COL["x_v_mps"]] = speed + rng.normal(0, 0.3, n)
    rows[:, COL["x_a_mps2"]] = rng.normal(0, 0.5, n)
    rows[:, COL["yaw_rate_radps"]] = 0.2 * np.sin(3 * t + seed) + rng.normal(0, 0.01, n)
    rows[:, COL["y_a_mps2"]] = 4.0 * np.sin(3 * t + seed) + rng.normal(0, 0.3, n)
    rows[:, COL["stl_m"]] = 0.03 * np.sin(3 * t + seed + 0.2) + rng.normal(0, 0.001, n)
    return rows, np.arange(n, dtype=np.int64) * STEP_NS


MIRRORED = ("y_v_mps", "y_a_mps2", "yaw_rate_radps", "stl_m")


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), speed=st.floats(5.0, 40.0))
def test_mirrored_steering_gives_mirrored_beta(seed: int, speed: float) -> None:
    rows, stamps = _random_drive(seed, 200, speed)
    mirror = rows.copy()
    for name in MIRRORED:
        mirror[:, COL[name]] *= -1.0
    a, b = create_backend("ukf", {}, 100), create_backend("ukf", {}, 100)
    for ea, eb in zip(_feed(a, rows, stamps), _feed(b, mirror, stamps), strict=True):
        assert ea is not None and eb is not None
        # Sigma points are drawn in another order for the mirrored state: equal to rounding.
        assert eb.beta_rad == pytest.approx(-ea.beta_rad, abs=1e-12)
        assert eb.variance_rad2 == pytest.approx(ea.variance_rad2, rel=1e-9)
    assert a.state["road_friction"] == pytest.approx(b.state["road_friction"], abs=1e-12)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    steps=st.lists(
        st.tuples(
            st.floats(0.0, 100.0),  # X_v
            st.floats(-50.0, 50.0),  # X_a
            st.floats(-50.0, 50.0),  # Y_a
            st.floats(-5.0, 5.0),  # yaw rate
            st.floats(-0.5, 0.5),  # STL
            st.sampled_from([0, 1, 1, 1, 2, 7, 400]),  # dt in sample periods (0: repeat)
        ),
        min_size=1,
        max_size=40,
    )
)
def test_never_nan_or_inf_whatever_the_in_range_input(steps: list[tuple]) -> None:
    # Everything the runtime's input limits let through, with repeated stamps and gaps.
    backend = create_backend("ukf", {}, 100)
    rows = np.zeros((1, len(CHANNELS)))
    stamp = 0
    for x_v, x_a, y_a, r, stl, gap in steps:
        stamp += gap * STEP_NS
        rows[0, [COL["x_v_mps"], COL["x_a_mps2"], COL["y_a_mps2"]]] = x_v, x_a, y_a
        rows[0, [COL["yaw_rate_radps"], COL["stl_m"]]] = r, stl
        est = backend.update(rows, np.array([stamp]))
        if est is None:
            continue
        assert math.isfinite(est.beta_rad) and abs(est.beta_rad) <= math.pi
        assert math.isfinite(est.variance_rad2) and est.variance_rad2 >= 0.0
        assert all(math.isfinite(v) for v in backend.state.values())


def test_a_non_finite_input_restarts_the_filter_and_gives_none() -> None:
    rows, stamps = _random_drive(1, 3)
    rows[1, COL["y_a_mps2"]] = math.nan
    backend = create_backend("ukf", {}, 100)
    out = _feed(backend, rows, stamps)
    assert out[0] is not None and out[1] is None
    fresh = create_backend("ukf", {}, 100)
    assert out[2] == fresh.update(rows[2:], stamps[2:])


def test_below_its_min_speed_gives_none_and_restarts() -> None:
    rows, stamps = _random_drive(2, 4)
    rows[2, COL["x_v_mps"]] = 2.5
    backend = create_backend("ukf", {"min_speed_mps": 3.0}, 100)
    out = _feed(backend, rows, stamps)
    assert out[0] is not None and out[1] is not None and out[2] is None
    # The filter restarted from its prior: the next estimate is a fresh filter's first.
    fresh = create_backend("ukf", {"min_speed_mps": 3.0}, 100)
    assert out[3] == fresh.update(rows[3:], stamps[3:])


def test_reset_forgets_the_state() -> None:
    rows, stamps = _random_drive(3, 50)
    used = create_backend("ukf", {}, 100)
    _feed(used, rows[:-1], stamps[:-1])
    used.reset()
    fresh = create_backend("ukf", {}, 100)
    assert used.update(rows, stamps) == fresh.update(rows, stamps)


def test_a_long_gap_or_a_stamp_going_back_restarts_and_a_repeated_stamp_does_not_predict() -> None:
    rows, stamps = _random_drive(4, 3)
    late = stamps.copy()
    late[2] = late[1] + round((MAX_GAP_S + 0.1) * 1e9)
    backend = create_backend("ukf", {}, 100)
    out = _feed(backend, rows, late)
    assert out[2] == create_backend("ukf", {}, 100).update(rows[2:], late[2:])
    # A stamp going back restarts too.
    back = np.array([stamps[0], stamps[1], stamps[0]], dtype=np.int64)
    out = _feed(create_backend("ukf", {}, 100), rows, back)
    assert out[2] == create_backend("ukf", {}, 100).update(rows[2:], back[2:])
    # A repeated stamp: no prediction (dt = 0), a second measurement update only.
    backend = create_backend("ukf", {}, 100)
    same = np.array([0, 0, STEP_NS], dtype=np.int64)
    out = _feed(backend, rows, same)
    assert all(e is not None and math.isfinite(e.beta_rad) for e in out)


def test_dropped_samples_are_integrated_in_substeps() -> None:
    # Every 2nd sample missing: about the same estimate as with all of them.
    samples = exact_samples(
        simulate(load_vehicle("paper_sedan"), Maneuver("gap", "sine_steer", 3.0, 80.0, 300.0)),
    )
    rows = np.column_stack([getattr(samples, c) for c in CHANNELS])
    stamps = np.asarray(samples.stamp_ns)
    full = _feed(create_backend("ukf", {}, 100), rows, stamps)[-1]
    half = _feed(create_backend("ukf", {}, 100), rows[::2], stamps[::2])[-1]
    assert full is not None and half is not None
    assert half.beta_rad == pytest.approx(full.beta_rad, abs=math.radians(0.02))


@pytest.mark.parametrize("memory_s", [0.5, 1e6])
def test_friction_uncertainty_stays_bounded_where_nothing_observes_it(memory_s: float) -> None:
    # 4 s straight ahead: μ unobservable. Its 1-σ tends to q·√(memory/2) with a 0.5-s
    # memory (0.079 with the default q 0.158); without memory (a pure random walk) it grows
    # as √(σ₀² + q² t) (0.44).
    q = float(DEFAULTS["process_sigma_friction_per_sqrt_s"])
    sigma0 = float(DEFAULTS["friction_initial_sigma"])
    expected = q * math.sqrt(memory_s / 2.0) if memory_s < 10 else math.hypot(sigma0, q * 2.0)
    rows, stamps = _random_drive(6, 1600)
    rows[:, [COL["yaw_rate_radps"], COL["y_a_mps2"], COL["stl_m"]]] = 0.0
    backend = create_backend("ukf", {"friction_memory_s": memory_s}, 100)
    for k in range(len(rows)):
        backend.update(rows[k : k + 1], stamps[k : k + 1])
    assert backend.state_sigma["road_friction"] == pytest.approx(expected, rel=0.3)


def test_variance_comes_from_the_covariance_of_v_y_over_v_x_squared() -> None:
    rows, stamps = _random_drive(5, 100)
    backend = create_backend("ukf", {}, 100)
    est = _feed(backend, rows, stamps)[-1]
    assert est is not None
    v_x = backend.state["v_x_mps"]
    p_vy = backend.state_sigma["v_y_mps"] ** 2
    # β ≈ v_y/v_x for small β: var(β) ≈ P_vy,vy / v_x².
    assert est.variance_rad2 == pytest.approx(p_vy / v_x**2, rel=0.05)


@pytest.mark.parametrize("source", ["vehicle", "recordings", "description"])
def test_a_params_file_may_say_where_its_axle_curves_come_from(tmp_path: Path, source: str) -> None:
    plain = tmp_path / "plain.yaml"
    plain.write_text(yaml.safe_dump(_good_mapping()))
    marked = tmp_path / "marked.yaml"
    marked.write_text(yaml.safe_dump(_good_mapping() | {"axles_from": source}))
    a = create_backend("ukf", {"params_file": str(plain)}, 100).params
    b = create_backend("ukf", {"params_file": str(marked)}, 100).params
    assert a.axles_from == "vehicle" and b.axles_from == source
    assert a == b  # the filter reads the same car


def test_an_unknown_axle_source_is_refused_naming_the_file(tmp_path: Path) -> None:
    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump(_good_mapping() | {"axles_from": "guess"}))
    with pytest.raises(BackendError, match=r"axles_from must be one of .*'guess'") as info:
        create_backend("ukf", {"params_file": str(path)}, 100)
    assert str(path) in str(info.value)


# --- the model on all sigma points at once ---------------------------------------------


@settings(max_examples=20, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    relaxation=st.booleans(),
    friction=st.booleans(),
    disturbance=st.booleans(),
)
def test_the_model_on_all_sigma_points_at_once_is_the_model_on_each_point(
    seed: int, relaxation: bool, friction: bool, disturbance: bool
) -> None:
    """fx, hx and the cross covariance take every sigma point in one call; each point's
    row is what that point alone gives, and the covariance filterpy's own loop's."""
    from filterpy.kalman import UnscentedKalmanFilter

    values = {"tyre_relaxation": relaxation, "estimate_friction": friction}
    values["estimate_disturbance"] = disturbance
    backend = create_backend("ukf", {**DEFAULTS, "params_file": "paper_sedan", **values}, 100)
    rng = np.random.default_rng(seed)
    # Plausible states, and some a sigma point may reach: v_x below MIN_VX_MPS, μ ≤ 0.
    spread = {"v_x_mps": (0.1, 40.0), "v_y_mps": (-3.0, 3.0), "yaw_rate_radps": (-1.0, 1.0)}
    spread |= {"slip_front_rad": (-0.2, 0.2), "slip_rear_rad": (-0.2, 0.2)}
    spread |= {"road_friction": (-0.1, 1.2), "lateral_disturbance_mps2": (-2.0, 2.0)}
    points = 2 * len(backend.state_names) + 1  # Van der Merwe's sigma points
    x = np.column_stack([rng.uniform(*spread[n], points) for n in backend.state_names])
    inputs = {"delta0": 0.02, "delta1": -0.01, "ax0": -3.0, "ax1": 2.0}
    at_once = backend._fx(x, 0.0025, **inputs)
    each = np.vstack([backend._fx(row[None, :], 0.0025, **inputs) for row in x])
    np.testing.assert_allclose(at_once, each, rtol=1e-14, atol=1e-15)
    h_at_once = backend._hx(x, delta=0.03, a_x=-2.0)
    h_each = np.vstack([backend._hx(row[None, :], delta=0.03, a_x=-2.0) for row in x])
    np.testing.assert_allclose(h_at_once, h_each, rtol=1e-14, atol=1e-15)
    assert h_at_once.shape == (points, 3)
    ukf = backend._ukf
    mean, z = x.mean(axis=0), h_at_once.mean(axis=0)
    ours = ukf.cross_variance(mean, z, x, h_at_once)
    theirs = UnscentedKalmanFilter.cross_variance(ukf, mean, z, x, h_at_once)
    np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=1e-12)
