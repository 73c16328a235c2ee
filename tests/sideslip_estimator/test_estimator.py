"""The estimator core: checks, alignment, stamp rules, window fill and min speed, fed
through the same decoded fields the node passes in (no DDS, no rclpy)."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sideslip_estimator.backends import Estimate, create_backend
from sideslip_estimator.estimator import Estimator, EstimatorParams, Output
from sideslip_estimator.inputs import InputLimits, InputRejected
from sideslip_msgs_py.messages import ImuFields, SteeringFields, TwistFields
from sideslip_msgs_py.sample import SampleArrays
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.sensors import exact_samples
from sideslip_sim.simulate import simulate
from sideslip_sim.vehicle import load_vehicle

IMU, TWIST, STEERING = "/vehicle/imu", "/vehicle/twist", "/vehicle/steering"
STEP_NS = 2_500_000  # 400 Hz
T0_NS = 1_700_000_000 * 10**9
WINDOW = 10


def _estimator(
    backend: str = "kinematic", window_steps: int = WINDOW, **params: object
) -> Estimator:
    return Estimator(
        create_backend(backend, {}, window_steps),
        EstimatorParams(window_steps=window_steps, **params),  # type: ignore[arg-type]
    )


def _step(
    est: Estimator,
    k: int,
    *,
    x_v: float = 20.0,
    y_v: float = 0.5,
    x_a: float = 0.1,
    y_a: float = 2.0,
    r: float = 0.1,
    stl: float = 0.01,
) -> Output | None:
    """Twist, steering and IMU of step ``k`` (all stamped alike), in that order."""
    stamp = T0_NS + k * STEP_NS
    est.on_twist(TWIST, TwistFields(stamp, x_v, y_v))
    est.on_steering(STEERING, SteeringFields(stamp, stl, 0.0))
    return est.on_imu(IMU, ImuFields(stamp, x_a, y_a, r))


def _run(est: Estimator, steps: range | list[int], **values: float) -> list[Output | None]:
    return [_step(est, k, **values) for k in steps]


# --- window fill ------------------------------------------------------------------------------


def test_no_estimate_until_the_window_holds_window_steps_accepted_samples() -> None:
    est = _estimator()
    outs = _run(est, range(WINDOW))
    assert outs[:-1] == [None] * (WINDOW - 1)
    assert outs[-1] is not None
    assert est.fill == (WINDOW, WINDOW)
    assert est.stats.accepted == WINDOW and est.stats.estimates == 1


def test_every_sample_after_the_window_filled_gives_an_estimate_stamped_with_it() -> None:
    est = _estimator()
    outs = _run(est, range(3 * WINDOW))
    stamps = [o.stamp_ns for o in outs if o is not None]
    assert stamps == [T0_NS + k * STEP_NS for k in range(WINDOW - 1, 3 * WINDOW)]
    assert outs[-1] is not None and outs[-1].v_x_mps == 20.0
    assert outs[-1].estimate.beta_rad == math.atan2(0.5, 20.0)


def test_rejected_samples_do_not_count_towards_the_window() -> None:
    est = _estimator()
    _run(est, range(WINDOW - 1))
    stamp = T0_NS + (WINDOW - 1) * STEP_NS
    with pytest.raises(InputRejected):
        est.on_imu(IMU, ImuFields(stamp, math.nan, 0.0, 0.0))
    assert est.fill == (WINDOW - 1, WINDOW)
    assert _step(est, WINDOW) is not None


# --- alignment --------------------------------------------------------------------------------


def test_imu_before_any_twist_is_rejected_as_no_twist() -> None:
    est = _estimator()
    est.on_steering(STEERING, SteeringFields(T0_NS, 0.0, 0.0))
    with pytest.raises(InputRejected) as info:
        est.on_imu(IMU, ImuFields(T0_NS, 0.0, 0.0, 0.0))
    assert info.value.reason == "no_twist"
    assert est.stats.rejected["no_twist"] == 1 and "no twist" in est.stats.last_rejection


def test_imu_before_any_steering_is_rejected_as_no_steering() -> None:
    est = _estimator()
    est.on_twist(TWIST, TwistFields(T0_NS, 20.0, 0.0))
    with pytest.raises(InputRejected) as info:
        est.on_imu(IMU, ImuFields(T0_NS, 0.0, 0.0, 0.0))
    assert info.value.reason == "no_steering"
    assert est.stats.rejected["no_steering"] == 1


@pytest.mark.parametrize("which", ["twist", "steering"])
@pytest.mark.parametrize("direction", [-1, 1])
def test_twist_or_steering_beyond_max_input_age_is_rejected_as_stale(
    which: str, direction: int
) -> None:
    est = _estimator(max_input_age_s=0.05)  # nothing held yet but what is sent here
    imu_stamp = T0_NS + WINDOW * STEP_NS
    off = imu_stamp + direction * 60_000_000  # 60 ms before / after the IMU stamp
    twist_stamp = off if which == "twist" else imu_stamp
    steer_stamp = off if which == "steering" else imu_stamp
    est.on_twist(TWIST, TwistFields(twist_stamp, 20.0, 0.5))
    est.on_steering(STEERING, SteeringFields(steer_stamp, 0.0, 0.0))
    with pytest.raises(InputRejected) as info:
        est.on_imu(IMU, ImuFields(imu_stamp, 0.0, 0.0, 0.0))
    assert info.value.reason == f"stale_{which}"
    assert est.stats.rejected[f"stale_{which}"] == 1


def test_the_latest_twist_and_steering_are_used() -> None:
    est = _estimator()
    _run(est, range(WINDOW - 1))
    stamp = T0_NS + (WINDOW - 1) * STEP_NS
    est.on_twist(TWIST, TwistFields(stamp - STEP_NS, 10.0, 1.0))
    est.on_twist(TWIST, TwistFields(stamp, 20.0, -3.0))
    est.on_steering(STEERING, SteeringFields(stamp - STEP_NS, 0.2, 0.0))
    est.on_steering(STEERING, SteeringFields(stamp, 0.03, 0.0))
    out = est.on_imu(IMU, ImuFields(stamp, 0.4, 1.5, -0.2))
    assert out is not None and out.estimate.beta_rad == math.atan2(-3.0, 20.0)
    np.testing.assert_array_equal(est.window.rows()[-1], [20.0, -3.0, 0.4, 1.5, -0.2, 0.03])


def test_twist_within_max_age_is_reused_for_several_imu_samples() -> None:
    est = _estimator(max_input_age_s=0.05)
    est.on_twist(TWIST, TwistFields(T0_NS, 20.0, 0.5))
    est.on_steering(STEERING, SteeringFields(T0_NS, 0.0, 0.0))
    for k in range(WINDOW):  # 10 IMU samples = 22.5 ms after the twist
        out = est.on_imu(IMU, ImuFields(T0_NS + k * STEP_NS, 0.0, 0.0, 0.0))
    assert out is not None and est.stats.accepted == WINDOW


# --- bad values ------------------------------------------------------------------------------

BAD_FIELDS = [
    ("imu", "x_a_mps2", "linear_acceleration.x"),
    ("imu", "y_a_mps2", "linear_acceleration.y"),
    ("imu", "yaw_rate_radps", "angular_velocity.z"),
    ("twist", "x_v_mps", "twist.linear.x"),
    ("twist", "y_v_mps", "twist.linear.y"),
    ("steering", "stl_m", "position[steering_rack]"),
]


def _send(est: Estimator, kind: str, stamp: int, **override: float) -> Output | None:
    if kind == "imu":
        f = ImuFields(stamp, 0.1, 2.0, 0.1)._replace(**override)
        return est.on_imu(IMU, f)
    if kind == "twist":
        est.on_twist(TWIST, TwistFields(stamp, 20.0, 0.5)._replace(**override))
        return None
    est.on_steering(STEERING, SteeringFields(stamp, 0.01, 0.0)._replace(**override))
    return None


@pytest.mark.parametrize(("kind", "attr", "field"), BAD_FIELDS, ids=[b[1] for b in BAD_FIELDS])
@pytest.mark.parametrize(
    ("value", "reason"),
    [(math.nan, "non_finite"), (math.inf, "non_finite"), (-math.inf, "non_finite"),
     (1e9, "out_of_range"), (-1e9, "out_of_range")],
)  # fmt: skip
def test_bad_value_in_any_field_is_rejected_with_reason_topic_and_field(
    kind: str, attr: str, field: str, value: float, reason: str
) -> None:
    est = _estimator()
    _run(est, range(WINDOW))
    stamp = T0_NS + WINDOW * STEP_NS
    topic = {"imu": IMU, "twist": TWIST, "steering": STEERING}[kind]
    with pytest.raises(InputRejected) as info:
        _send(est, kind, stamp, **{attr: value})
    assert info.value.reason == reason
    assert topic in str(info.value) and field in str(info.value)
    assert est.stats.rejected[reason] == 1
    assert est.stats.last_rejection == str(info.value)
    # A rejected twist or steering leaves the previous good value in use.
    out = _step(est, WINDOW + 1)
    assert out is not None and math.isfinite(out.estimate.beta_rad)


_ANY_FLOAT = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-200.0, 200.0),
    st.sampled_from([0.0, -0.0, 1e-300, 5e-324]),
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    backend=st.sampled_from(["kinematic", "single_track"]),
    values=st.lists(st.tuples(*[_ANY_FLOAT] * 6), min_size=1, max_size=40),
)
def test_estimator_never_returns_a_non_finite_estimate(
    backend: str, values: list[tuple[float, ...]]
) -> None:
    est = _estimator(backend, window_steps=3, min_speed_mps=0.0)
    for k, (x_v, y_v, x_a, y_a, r, stl) in enumerate(values):
        stamp = T0_NS + k * STEP_NS
        with contextlib.suppress(InputRejected):
            est.on_twist(TWIST, TwistFields(stamp, x_v, y_v))
        with contextlib.suppress(InputRejected):
            est.on_steering(STEERING, SteeringFields(stamp, stl, 0.0))
        try:
            out = est.on_imu(IMU, ImuFields(stamp, x_a, y_a, r))
        except InputRejected:
            continue
        if out is not None:
            assert math.isfinite(out.estimate.beta_rad)
            assert math.isfinite(out.estimate.variance_rad2) and out.estimate.variance_rad2 >= 0
            assert math.isfinite(out.v_x_mps)


class _NanBackend:
    """A back-end whose model went wrong: it returns NaN."""

    name = "nan"
    model_id = "nan-model"

    def reset(self) -> None:
        pass

    def update(
        self, rows: npt.NDArray[np.float64], stamps_ns: npt.NDArray[np.int64]
    ) -> Estimate | None:
        return Estimate(math.nan, 0.0)


def test_non_finite_model_output_is_rejected_not_published() -> None:
    est = Estimator(_NanBackend(), EstimatorParams(window_steps=2))
    assert _step(est, 0) is None  # window not full: nothing checked yet
    with pytest.raises(InputRejected) as info:
        _step(est, 1)
    assert info.value.reason == "model_non_finite" and "nan-model" in str(info.value)
    assert est.stats.rejected["model_non_finite"] == 1 and est.stats.estimates == 0


def test_reject_message_counts_an_undecodable_message() -> None:
    est = _estimator()
    err = est.reject_message("bad_message", "/vehicle/steering: no 'steering_rack'")
    assert isinstance(err, InputRejected) and err.reason == "bad_message"
    assert est.stats.rejected["bad_message"] == 1
    assert est.stats.last_rejection == "/vehicle/steering: no 'steering_rack'"


# --- stamps -------------------------------------------------------------------------------------


def test_stamp_going_backwards_restarts_the_window_until_it_is_refilled() -> None:
    est = _estimator()
    _run(est, range(100))  # 250 ms: longer than max_gap_s
    assert est.window.full
    # A bag played in a loop: stamps jump back to the start.
    outs = _run(est, range(WINDOW))
    assert est.stats.resets["stamp_backwards"] == 1
    assert outs[:-1] == [None] * (WINDOW - 1) and outs[-1] is not None
    assert est.window.stamps_ns()[0] == T0_NS  # nothing of the old stretch is kept


def test_restart_resets_the_backend_so_no_old_samples_are_averaged() -> None:
    est = Estimator(
        create_backend("kinematic", {"smoothing_steps": WINDOW}, WINDOW),
        EstimatorParams(window_steps=WINDOW),
    )
    _run(est, range(100, 100 + WINDOW), y_v=5.0)
    outs = _run(est, range(WINDOW), y_v=-1.0)  # backwards: the y_v=5 rows must be gone
    assert outs[-1] is not None and outs[-1].estimate.beta_rad == math.atan2(-1.0, 20.0)


def test_duplicate_imu_stamp_is_rejected_and_the_window_kept() -> None:
    est = _estimator()
    _run(est, range(WINDOW))
    with pytest.raises(InputRejected) as info:
        _step(est, WINDOW - 1)
    assert info.value.reason == "duplicate_stamp"
    assert est.stats.rejected["duplicate_stamp"] == 1
    assert not est.stats.resets and est.fill == (WINDOW, WINDOW)
    assert _step(est, WINDOW) is not None


def test_gap_longer_than_max_gap_restarts_the_window() -> None:
    est = _estimator(max_gap_s=0.1)
    _run(est, range(2 * WINDOW))
    skip = 41  # 41 steps = 102.5 ms > 100 ms
    out = _step(est, 2 * WINDOW - 1 + skip)
    # Held: a pause or one wrong stamp? The next message decides.
    assert out is None and est.held == 1 and not est.stats.resets
    outs = _run(est, range(2 * WINDOW + skip, 2 * WINDOW + skip + WINDOW - 1))
    assert est.stats.resets["gap"] == 1 and est.held == 0
    assert est.stats.dropped == 0  # a pause is not counted as drops
    # The held message entered the new window first: no sample of the new line lost.
    assert outs[-1] is not None and all(o is None for o in outs[:-1])
    assert est.window.stamps_ns()[0] == T0_NS + (2 * WINDOW - 1 + skip) * STEP_NS


def test_gap_of_exactly_max_gap_keeps_the_window() -> None:
    est = _estimator(max_gap_s=0.1)
    _run(est, range(2 * WINDOW))
    out = _step(est, 2 * WINDOW - 1 + 40)  # 40 steps = 100 ms
    assert out is not None and not est.stats.resets and est.stats.dropped == 39


@pytest.mark.parametrize("missing", [1, 3, 20])
def test_small_gaps_count_the_missing_samples_as_dropped(missing: int) -> None:
    est = _estimator()
    _run(est, range(2 * WINDOW))
    out = _step(est, 2 * WINDOW + missing)
    assert est.stats.dropped == missing
    assert out is not None and not est.stats.resets and est.window.full


def test_jitter_below_one_and_a_half_periods_is_not_a_drop() -> None:
    est = _estimator()
    stamps = T0_NS + np.cumsum(np.tile([2_000_000, 3_000_000, 3_700_000, 1_300_000], 10))
    for s in stamps:
        est.on_twist(TWIST, TwistFields(int(s), 20.0, 0.0))
        est.on_steering(STEERING, SteeringFields(int(s), 0.0, 0.0))
        est.on_imu(IMU, ImuFields(int(s), 0.0, 0.0, 0.0))
    assert est.stats.dropped == 0 and not est.stats.resets


def test_rejected_imu_samples_still_advance_the_stamp() -> None:
    # A NaN IMU message was received (not lost): the next sample is not a drop.
    est = _estimator()
    _run(est, range(2 * WINDOW))
    with pytest.raises(InputRejected):
        _step(est, 2 * WINDOW, r=math.nan)
    _step(est, 2 * WINDOW + 1)
    assert est.stats.dropped == 0


# --- speed --------------------------------------------------------------------------------------


def test_below_min_speed_gives_no_estimate_and_is_counted() -> None:
    est = _estimator(min_speed_mps=1.0)
    outs = _run(est, range(2 * WINDOW), x_v=0.5, y_v=0.1)
    assert outs == [None] * (2 * WINDOW)
    assert est.stats.below_min_speed == WINDOW + 1  # every sample once the window is full
    assert est.stats.estimates == 0 and est.stats.accepted == 2 * WINDOW
    assert _step(est, 2 * WINDOW, x_v=1.0) is not None  # at the limit: estimated


@pytest.mark.parametrize("backend", ["kinematic", "single_track"])
def test_standing_still_is_counted_below_min_speed(backend: str) -> None:
    # A wheel-speed sensor reports exactly 0 at rest. The back-end has no estimate
    # then, but the status must still learn why nothing is published.
    est = _estimator(backend, min_speed_mps=1.0)
    outs = _run(est, range(2 * WINDOW), x_v=0.0, y_v=0.0)
    assert outs == [None] * (2 * WINDOW)
    assert est.stats.below_min_speed == WINDOW + 1


def test_reversing_gives_no_estimate() -> None:
    est = _estimator(min_speed_mps=1.0)
    outs = _run(est, range(2 * WINDOW), x_v=-5.0, y_v=0.1)
    assert outs == [None] * (2 * WINDOW) and est.stats.below_min_speed == WINDOW + 1


# --- parameters ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "value"),
    [("window_steps", 0), ("max_input_age_s", 0.0), ("max_input_age_s", math.nan),
     ("max_gap_s", -1.0), ("max_gap_s", math.inf), ("min_speed_mps", -0.1),
     ("min_speed_mps", math.nan)],
)  # fmt: skip
def test_bad_estimator_params_are_refused_naming_the_parameter(name: str, value: float) -> None:
    with pytest.raises(ValueError, match=name):
        EstimatorParams(**{name: value})  # type: ignore[arg-type]


def test_estimator_uses_its_input_limits() -> None:
    est = _estimator(limits=InputLimits(speed_mps=10.0))
    with pytest.raises(InputRejected) as info:
        _step(est, 0, x_v=11.0)
    assert info.value.reason == "out_of_range"


# --- a simulated run ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def sine_run() -> SampleArrays:
    """3 s of noise-free sine steer at 72 km/h from the 14-DOF model."""
    m = Maneuver("est_sine", "sine_steer", 3.0, 72.0, 150.0, ay_fraction=0.4)
    return exact_samples(simulate(load_vehicle("paper_sedan"), m), start_stamp_ns=T0_NS)


def _feed(est: Estimator, s: SampleArrays) -> Iterator[tuple[int, Output | None]]:
    for i in range(len(s)):
        stamp = int(s.stamp_ns[i])
        est.on_twist(TWIST, TwistFields(stamp, float(s.x_v_mps[i]), float(s.y_v_mps[i])))
        est.on_steering(
            STEERING, SteeringFields(stamp, float(s.stl_m[i]), float(s.stl_rate_mps[i]))
        )
        imu = ImuFields(
            stamp, float(s.x_a_mps2[i]), float(s.y_a_mps2[i]), float(s.yaw_rate_radps[i])
        )
        yield i, est.on_imu(IMU, imu)


def test_raw_kinematic_estimate_of_exact_samples_is_the_ground_truth(
    sine_run: SampleArrays,
) -> None:
    est = _estimator(window_steps=100)
    truth = sine_run.beta_rad()
    results = list(_feed(est, sine_run))
    outs = [(i, o) for i, o in results if o is not None]
    assert [i for i, _ in outs] == list(range(99, len(sine_run)))
    for i, o in outs:
        assert o.estimate.beta_rad == truth[i]
        assert o.stamp_ns == sine_run.stamp_ns[i]
    assert est.stats.rejected == {} and est.stats.dropped == 0 and not est.stats.resets
    assert est.input_rate_hz == pytest.approx(400.0)


class _FaultyBackend(_NanBackend):
    """A back-end that raises (a shape error in a model, a singular matrix, ...)."""

    model_id = "faulty-model"

    def update(
        self, rows: npt.NDArray[np.float64], stamps_ns: npt.NDArray[np.int64]
    ) -> Estimate | None:
        raise np.linalg.LinAlgError("singular matrix")


class _RightAngleBackend(_NanBackend):
    model_id = "right-angle-model"

    def update(
        self, rows: npt.NDArray[np.float64], stamps_ns: npt.NDArray[np.int64]
    ) -> Estimate | None:
        return Estimate(math.pi / 2, 0.0)


def test_a_backend_exception_is_a_rejection_and_restarts_the_window() -> None:
    est = Estimator(_FaultyBackend(), EstimatorParams(window_steps=2))
    with pytest.raises(InputRejected) as info:
        _step(est, 0)
    assert info.value.reason == "model_error" and "singular matrix" in str(info.value)
    assert est.stats.resets["model_error"] == 1 and len(est.window) == 0


def test_a_backend_beta_of_90_degrees_is_rejected() -> None:
    est = Estimator(_RightAngleBackend(), EstimatorParams(window_steps=1))
    with pytest.raises(InputRejected) as info:
        _step(est, 0)
    assert info.value.reason == "model_out_of_range"


def test_a_lower_input_rate_counts_drops_and_shows_as_a_measured_rate() -> None:
    # Drops are counted against the model's rate and never withdrawn: under load long
    # intervals in a row are losses, and a slower source is told by its measured rate.
    est = _estimator(max_gap_s=1.0)
    _run(est, range(0, 100))  # 400 Hz
    assert est.stats.dropped == 0 and est.input_rate_hz == pytest.approx(400.0)
    _run(est, range(100, 400, 4))  # then 100 Hz: every 4th step
    assert est.stats.dropped == 3 * 74  # 75 samples, 74 intervals of 4 steps
    assert est.input_rate_hz == pytest.approx(100.0)


def test_a_stamp_jump_back_starts_a_new_line_and_forgets_the_old_inputs() -> None:
    est = _estimator()
    _run(est, range(0, 50))
    out = _run(est, range(-1000, -1000 + 3 * WINDOW))
    assert est.stats.resets["stamp_backwards"] == 1
    assert out[-1] is not None  # refilled from the new time line


# --- one bad message costs that message -------------------------------------------------------


def _published(est: Estimator) -> int:
    """Messages the core has accounted for: accepted, rejected or dropped (+ one held)."""
    s = est.stats
    return s.accepted + sum(s.rejected.values()) + s.dropped + est.held


def test_one_late_message_is_skipped_without_restarting_the_window() -> None:
    est = _estimator()
    _run(est, [k for k in range(2 * WINDOW) if k != 2 * WINDOW - 5])
    assert est.stats.dropped == 1
    with pytest.raises(InputRejected) as info:
        _step(est, 2 * WINDOW - 5)  # the missing IMU message arrives 10 ms late
    assert info.value.reason == "late_stamp" and "out of order" in str(info.value)
    assert not est.stats.resets and est.window.full and est.stats.dropped == 0
    assert _step(est, 2 * WINDOW) is not None  # the very next sample has its estimate
    assert _published(est) == 2 * WINDOW + 1


def test_a_message_overtaken_by_the_next_moves_from_dropped_to_late() -> None:
    est = _estimator()
    _run(est, range(2 * WINDOW))
    assert _step(est, 2 * WINDOW + 1) is not None  # step 2W is missing so far: a drop
    assert est.stats.dropped == 1
    with pytest.raises(InputRejected):
        _step(est, 2 * WINDOW)  # ... it arrives after all: skipped, not dropped
    assert est.stats.dropped == 0 and est.stats.rejected["late_stamp"] == 1
    assert _published(est) == 2 * WINDOW + 2


def test_a_future_stamp_within_max_gap_is_taken_back_by_the_next_message() -> None:
    est = _estimator(max_gap_s=0.1)
    _run(est, range(2 * WINDOW))
    # Step 2W's message stamped 50 ms ahead: 20 "drops" until the next ones show it.
    _step(est, 2 * WINDOW + 20)
    assert est.stats.dropped == 20
    with pytest.raises(InputRejected):
        _step(est, 2 * WINDOW + 1)  # behind it: late, or its neighbour overtaken?
    outs = _run(est, range(2 * WINDOW + 2, 3 * WINDOW))  # a second: it was the stamp
    assert est.stats.future_stamps == 1 and est.stats.dropped == 0
    assert not est.stats.resets and est.stats.rejected == {"late_stamp": 1}
    assert all(o is not None for o in outs)  # it cost the one message behind it
    stamps = est.window.stamps_ns()
    assert np.all(np.diff(stamps) > 0)  # the wrong stamp was corrected in the window
    assert _published(est) == 3 * WINDOW


@pytest.mark.parametrize("offset_s", [1.0, -1.0, 3600.0])
def test_one_far_off_stamp_is_rejected_as_bad_stamp_and_costs_only_itself(
    offset_s: float,
) -> None:
    est = _estimator()
    _run(est, range(2 * WINDOW))
    wrong = 2 * WINDOW + round(offset_s * 400)
    assert _step(est, wrong) is None and est.held == 1
    outs = _run(est, range(2 * WINDOW, 3 * WINDOW))
    assert est.stats.rejected == {"bad_stamp": 1} and not est.stats.resets
    assert all(o is not None for o in outs)
    assert est.stats.dropped == 0 and _published(est) == 3 * WINDOW + 1


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    events=st.lists(
        st.sampled_from(["send", "send", "send", "drop", "duplicate", "swap"]),
        min_size=30,
        max_size=200,
    )
)
def test_every_published_message_is_accepted_rejected_or_dropped_exactly(
    events: list[str],
) -> None:
    """Drops, duplicates and neighbours swapped in transit: the counts add up to what
    the publisher sent, and none of it restarts the window."""
    est = _estimator(max_gap_s=0.1)
    _step(est, 0)
    sent, k, delivered = 1, 1, True
    for event in events:
        if event == "drop":
            sent, k, delivered = sent + 1, k + 1, False
            continue
        if event == "duplicate" and delivered:  # (a lost copy of a lost one is unseen)
            with contextlib.suppress(InputRejected):
                _step(est, k - 1)
            sent += 1
            continue
        delivered = True
        order = [k + 1, k] if event == "swap" else [k]
        for step in order:
            with contextlib.suppress(InputRejected):
                _step(est, step)
        sent, k = sent + len(order), k + len(order)
    _step(est, k)  # a last message shows any drop before it
    sent += 1
    assert _published(est) == sent
    assert not est.stats.resets


# --- the model's rate ------------------------------------------------------------------------


class _RateBound:
    """A real kinematic back-end that declares a model step, as a trained network does."""

    def __init__(self, period_s: float) -> None:
        self._inner = create_backend("kinematic", {}, WINDOW)
        self.name, self.model_id = "rate_bound", "kinematic at a fixed step"
        self.sample_period_s = period_s

    def reset(self) -> None:
        self._inner.reset()

    def update(self, rows, stamps_ns):  # type: ignore[no-untyped-def]
        return self._inner.update(rows, stamps_ns)


def test_a_model_fed_another_rate_than_its_own_publishes_nothing() -> None:
    est = Estimator(_RateBound(0.0025), EstimatorParams(window_steps=WINDOW, max_gap_s=1.0))
    assert est.expected_rate_hz == pytest.approx(400.0)
    outs = _run(est, range(0, 400, 2))  # 200 Hz into a 400-Hz model
    assert est.rate_refused and est.input_rate_hz == pytest.approx(200.0)
    assert all(o is None for o in outs[WINDOW:]) and est.stats.wrong_rate > 0
    assert est.stats.estimates == 0
    outs = _run(est, range(400, 600))  # back at 400 Hz: estimates again
    assert not est.rate_refused and outs[-1] is not None


def test_a_rate_free_back_end_runs_at_any_rate_and_counts_against_400_hz() -> None:
    est = _estimator(max_gap_s=1.0)
    assert est.model_rate_hz is None and est.expected_rate_hz == 400.0
    outs = _run(est, range(0, 400, 4))  # 100 Hz
    assert not est.rate_refused and outs[-1] is not None
    est = _estimator(max_gap_s=1.0, input_rate_hz=100.0)  # told the source's rate
    _run(est, range(0, 400, 4))
    assert est.stats.dropped == 0
