"""The status diagnostic: OK while estimating, WARN when degraded, ERROR for unusable input,
with a one-line message and the values an operator reads; and what feeds it: the counters'
difference, the publishers seen on each input, and the tracker of what the node saw."""

from __future__ import annotations

import itertools
import math
from collections import Counter
from dataclasses import fields, replace

import pytest
from hypothesis import given
from hypothesis import strategies as st
from rclpy.topic_endpoint_info import TopicEndpointInfo, TopicEndpointTypeEnum

from sideslip_estimator.backends import create_backend
from sideslip_estimator.estimator import Estimator, EstimatorParams, EstimatorStats
from sideslip_estimator.inputs import InputRejected
from sideslip_estimator.status import (
    LEVEL_NAMES,
    LOG_EVERY_S,
    Counts,
    Observation,
    Status,
    StatusTracker,
    assess,
    input_publishers,
)
from sideslip_msgs_py.messages import ImuFields, SteeringFields, TwistFields
from sideslip_msgs_py.outputs import DIAGNOSTIC_ERROR, DIAGNOSTIC_OK, DIAGNOSTIC_WARN

TOPICS = ("/vehicle/imu", "/vehicle/twist", "/vehicle/steering")


def _obs(**changes: object) -> Observation:
    """A healthy observation: every input fresh, window full, estimates flowing."""
    healthy = Observation(
        input_ages_s=dict.fromkeys(TOPICS, 0.004),
        wrong_types=[],
        silence_timeout_s=0.1,
        window_fill=(100, 100),
        latencies_s=[0.0001, 0.0002, 0.0003],
        new=Counts(estimates=200),
    )
    # new_<counter>=n sets that counter of the Counts since the previous status.
    new = {k.removeprefix("new_"): changes.pop(k) for k in list(changes) if k.startswith("new_")}
    return replace(healthy, new=replace(healthy.new, **new), **changes)  # type: ignore[arg-type]


def _stats(**changes: object) -> EstimatorStats:
    stats = EstimatorStats(accepted=1000, estimates=901)
    for k, v in changes.items():
        setattr(stats, k, v)
    return stats


def _assess(obs: Observation, stats: EstimatorStats | None = None) -> Status:
    return assess(obs, stats or _stats(), "kinematic", "kinematic(smoothing_steps=1)")


def test_healthy_estimator_is_ok_and_says_estimating() -> None:
    status = _assess(_obs())
    assert status.level == DIAGNOSTIC_OK and status.message == "estimating"
    assert LEVEL_NAMES[status.level] == "OK"


def test_a_back_ends_standing_caveat_keeps_the_status_at_warn() -> None:
    caveat = "car x outside m.safetensors's 100 training cars (...): publishing the UKF's estimate"
    status = assess(_obs(), _stats(), "pso_lstm", "pso_lstm(m)", (caveat,))
    assert status.level == DIAGNOSTIC_WARN and status.message == caveat


def test_values_report_backend_model_fill_ages_latency_and_counters() -> None:
    stats = _stats(
        rejected=Counter({"non_finite": 2, "stale_twist": 1}),
        dropped=4,
        resets=Counter({"gap": 1}),
        last_rejection="/vehicle/imu: angular_velocity.z is nan",
    )
    v = _assess(_obs(), stats).values
    assert v["backend"] == "kinematic" and v["model_id"] == "kinematic(smoothing_steps=1)"
    assert v["window_fill"] == "100/100"
    assert v["input_age_s[/vehicle/imu]"] == "0.0040"
    assert v["latency_ms_p50"] == "0.200" and float(v["latency_ms_p99"]) == pytest.approx(0.298)
    assert v["estimates"] == "901" and v["accepted_samples"] == "1000"
    assert v["rejected_samples"] == "3"
    assert v["rejected[non_finite]"] == "2" and v["rejected[stale_twist]"] == "1"
    assert v["dropped_samples"] == "4"
    assert v["window_restarts"] == "1" and v["restarts[gap]"] == "1"
    assert v["last_rejection"] == "/vehicle/imu: angular_velocity.z is nan"
    assert all(isinstance(x, str) for x in v.values())


def test_values_without_latencies_or_rejections_say_so() -> None:
    v = _assess(_obs(latencies_s=[])).values
    assert v["latency_ms_p50"] == "n/a" and v["latency_ms_p99"] == "n/a"
    assert v["last_rejection"] == "-" and v["rejected_samples"] == "0"


def test_topic_never_heard_from_is_a_warning_naming_it() -> None:
    ages = dict.fromkeys(TOPICS, 0.004) | {"/vehicle/twist": None}
    status = _assess(_obs(input_ages_s=ages, window_fill=(0, 100)))
    assert status.level == DIAGNOSTIC_WARN
    assert "no message yet on /vehicle/twist" in status.message
    assert "window filling" not in status.message  # the cause is reported, not the symptom
    assert status.values["input_age_s[/vehicle/twist]"] == "never"


def test_topic_silent_longer_than_the_timeout_is_a_warning_with_its_age() -> None:
    ages = dict.fromkeys(TOPICS, 0.004) | {"/vehicle/steering": 0.5}
    status = _assess(_obs(input_ages_s=ages, window_fill=(30, 100)))
    assert status.level == DIAGNOSTIC_WARN
    assert "/vehicle/steering silent for 0.50 s" in status.message
    assert "window filling" not in status.message


def test_age_equal_to_the_timeout_is_not_silence() -> None:
    ages = dict.fromkeys(TOPICS, 0.1)
    assert _assess(_obs(input_ages_s=ages)).level == DIAGNOSTIC_OK


def test_window_filling_is_a_warning_with_the_fill() -> None:
    status = _assess(_obs(window_fill=(40, 100), new_estimates=0))
    assert status.level == DIAGNOSTIC_WARN and "window filling (40/100)" in status.message
    assert status.values["window_fill"] == "40/100"


def test_new_rejections_are_a_warning_quoting_the_last_one() -> None:
    stats = _stats(
        rejected=Counter({"stale_twist": 3}), last_rejection="twist stamp is -80.0 ms from ..."
    )
    status = _assess(_obs(new_rejections=3), stats)
    assert status.level == DIAGNOSTIC_WARN
    assert "3 input(s) rejected: twist stamp is -80.0 ms from ..." in status.message


def test_old_rejections_alone_do_not_keep_the_status_at_warn() -> None:
    stats = _stats(rejected=Counter({"stale_twist": 3}), last_rejection="old")
    assert _assess(_obs(new_rejections=0), stats).level == DIAGNOSTIC_OK


def test_new_drops_are_a_warning() -> None:
    status = _assess(_obs(new_drops=5))
    assert status.level == DIAGNOSTIC_WARN and "5 sample(s) dropped" in status.message


def test_new_restarts_are_a_warning() -> None:
    status = _assess(_obs(new_resets=2))
    assert status.level == DIAGNOSTIC_WARN and "window restarted 2 time(s)" in status.message


def test_below_min_speed_without_any_estimate_is_a_warning() -> None:
    status = _assess(_obs(new_below_min_speed=400, new_estimates=0))
    assert status.level == DIAGNOSTIC_WARN and "below min_speed_mps" in status.message
    # Some estimates in the period (the car just slowed down or started): still OK.
    assert _assess(_obs(new_below_min_speed=100, new_estimates=300)).level == DIAGNOSTIC_OK


def test_publisher_of_the_wrong_type_is_an_error_that_also_lists_warnings() -> None:
    wrong = ["/vehicle/imu: /bad_node publishes std_msgs/msg/String, expected sensor_msgs/msg/Imu"]
    status = _assess(_obs(wrong_types=wrong, new_drops=1))
    assert status.level == DIAGNOSTIC_ERROR and LEVEL_NAMES[status.level] == "ERROR"
    assert status.message.startswith(wrong[0])
    assert "1 sample(s) dropped" in status.message


def test_several_warnings_are_joined_in_one_line() -> None:
    status = _assess(_obs(new_drops=1, new_resets=1, new_rejections=1))
    assert status.level == DIAGNOSTIC_WARN
    assert status.message.count("; ") == 2 and "\n" not in status.message


def test_two_publishers_on_an_input_are_a_warning_naming_both() -> None:
    publishers = {"/vehicle/imu": ["/sim_a", "/sim_b"], "/vehicle/twist": ["/sim_a"]}
    status = _assess(_obs(publishers=publishers))
    assert status.level == DIAGNOSTIC_WARN
    assert "2 publishers on /vehicle/imu: /sim_a, /sim_b" in status.message
    assert "/vehicle/twist" not in status.message
    assert status.values["publishers[/vehicle/imu]"] == "/sim_a, /sim_b"


def test_a_frame_mismatch_is_a_warning() -> None:
    line = "/vehicle/imu: frame_id 'map', expected 'base_link' (used as if base_link)"
    status = _assess(_obs(wrong_frames=[line]))
    assert status.level == DIAGNOSTIC_WARN and line in status.message


def test_an_input_rate_off_the_expected_one_is_a_warning_naming_both_rates() -> None:
    status = _assess(_obs(input_rate_hz=100.0))
    assert status.level == DIAGNOSTIC_WARN
    assert "IMU at 100.0 Hz, expected 400 Hz" in status.message
    assert status.values["input_rate_hz"] == "100.0"
    assert _assess(_obs(input_rate_hz=398.0)).level == DIAGNOSTIC_OK


def test_counts_difference_is_what_happened_since_the_previous_status() -> None:
    before = Counts.of(_stats(dropped=3, rejected=Counter({"late_stamp": 1})))
    after = Counts.of(_stats(dropped=5, rejected=Counter({"late_stamp": 1, "bad_stamp": 2})))
    assert after - before == Counts(rejections=2, drops=2)


def test_a_model_refusing_the_input_rate_is_an_error_naming_both_rates() -> None:
    status = _assess(_obs(input_rate_hz=200.0, rate_refused=True, new_estimates=0))
    assert status.level == DIAGNOSTIC_ERROR
    assert "IMU at 200.0 Hz, the model expects 400 Hz: no estimate" in status.message


def test_the_published_sigma_is_summarised_in_degrees() -> None:
    v = _assess(_obs(sigmas_rad=[math.radians(0.05)] * 19 + [math.radians(0.5)])).values
    assert v["beta_sigma_deg_p50"] == "0.0500" and float(v["beta_sigma_deg_p95"]) > 0.05
    assert _assess(_obs()).values["beta_sigma_deg_p50"] == "n/a"


def test_the_share_of_estimates_whose_sigma_widened_beyond_the_fitted_driving_is_reported():
    sigmas = [math.radians(0.05)] * 15 + [math.radians(0.2)] * 5
    assert _assess(_obs(sigmas_rad=sigmas, widened=5)).values["sigma_widened"] == "0.250"
    assert _assess(_obs(sigmas_rad=sigmas)).values["sigma_widened"] == "0.000"
    assert _assess(_obs()).values["sigma_widened"] == "n/a"


# --- the counters' difference ------------------------------------------------------------------

counts = st.builds(Counts, **{f.name: st.integers(0, 10**9) for f in fields(Counts)})


def _plus(a: Counts, b: Counts) -> Counts:
    return Counts(**{f.name: getattr(a, f.name) + getattr(b, f.name) for f in fields(Counts)})


def test_counts_subtract_field_by_field() -> None:
    # Every field distinct, so a field taken from the wrong one (or left out) shows.
    names = [f.name for f in fields(Counts)]
    after = Counts(**{n: 100 * (i + 1) for i, n in enumerate(names)})
    before = Counts(**{n: i + 1 for i, n in enumerate(names)})
    diff = after - before
    assert [getattr(diff, n) for n in names] == [99 * (i + 1) for i in range(len(names))]


def test_counts_of_stats_sum_the_rejections_and_restarts_over_their_reasons() -> None:
    stats = _stats(
        rejected=Counter({"non_finite": 2, "stale_twist": 3}),
        resets=Counter({"gap": 1, "stamp_backwards": 4}),
        dropped=7,
        below_min_speed=11,
        no_estimate=13,
    )
    assert Counts.of(stats) == Counts(
        rejections=5, drops=7, resets=5, estimates=901, below_min_speed=11, no_estimate=13
    )


@given(a=counts, b=counts, c=counts)
def test_the_differences_of_successive_snapshots_add_up_to_the_whole_span(
    a: Counts, b: Counts, c: Counts
) -> None:
    # What two status periods reported adds up to what happened over both of them.
    assert _plus(c - b, b - a) == c - a
    assert _plus(b - a, a) == b
    assert a - a == Counts() and a - Counts() == a


# --- publishers on the input topics -----------------------------------------------------------

IMU_TYPE, TWIST_TYPE, STEERING_TYPE = (
    "sensor_msgs/msg/Imu",
    "geometry_msgs/msg/TwistStamped",
    "sensor_msgs/msg/JointState",
)


def _publisher(namespace: str, name: str, topic_type: str) -> TopicEndpointInfo:
    """A publisher as rclpy's get_publishers_info_by_topic reports it."""
    return TopicEndpointInfo(
        node_name=name,
        node_namespace=namespace,
        topic_type=topic_type,
        endpoint_type=TopicEndpointTypeEnum.PUBLISHER,
    )


def test_input_publishers_names_every_publisher_with_its_namespace() -> None:
    publishers, wrong = input_publishers(
        [
            (TOPICS[0], IMU_TYPE, [_publisher("/", "sim", IMU_TYPE),
                                   _publisher("/car/", "imu_driver", IMU_TYPE)]),
            (TOPICS[1], TWIST_TYPE, [_publisher("/car", "odometry", TWIST_TYPE)]),
            (TOPICS[2], STEERING_TYPE, []),
        ]
    )  # fmt: skip
    assert publishers == {
        "/vehicle/imu": ["/sim", "/car/imu_driver"],
        "/vehicle/twist": ["/car/odometry"],
        "/vehicle/steering": [],
    }
    assert wrong == []
    status = _assess(_obs(publishers=publishers))
    assert status.level == DIAGNOSTIC_WARN
    assert status.message == "2 publishers on /vehicle/imu: /sim, /car/imu_driver"
    assert status.values["publishers[/vehicle/twist]"] == "/car/odometry"
    assert status.values["publishers[/vehicle/steering]"] == "none"  # missing


def test_a_publisher_of_another_type_is_an_error_line_not_a_publisher() -> None:
    publishers, wrong = input_publishers(
        [
            (TOPICS[0], IMU_TYPE, [_publisher("/", "sim", IMU_TYPE),
                                   _publisher("/tools", "echo", "std_msgs/msg/String")]),
        ]
    )  # fmt: skip
    assert publishers == {"/vehicle/imu": ["/sim"]}
    assert wrong == [
        "/vehicle/imu: /tools/echo publishes std_msgs/msg/String, expected sensor_msgs/msg/Imu"
    ]
    status = _assess(_obs(publishers=publishers, wrong_types=wrong))
    assert status.level == DIAGNOSTIC_ERROR and status.message == wrong[0]


def test_a_publisher_whose_node_is_not_discovered_yet_is_named_so() -> None:
    publishers, _ = input_publishers(
        [(TOPICS[0], IMU_TYPE, [_publisher("/", "_NODE_NAME_UNKNOWN_", IMU_TYPE)])]
    )
    assert publishers == {"/vehicle/imu": ["(a node not discovered yet)"]}


# --- the tracker -------------------------------------------------------------------------------

IMU, TWIST, STEERING = TOPICS
STEP_NS = 2_500_000  # 400 Hz
T0_NS = 1_700_000_000 * 10**9
WINDOW = 10


def _core() -> Estimator:
    return Estimator(create_backend("kinematic", {}, WINDOW), EstimatorParams(window_steps=WINDOW))


def _tracker(core: Estimator, frame_id: str = "base_link") -> StatusTracker:
    return StatusTracker(core.stats, TOPICS, frame_id, silence_timeout_s=0.1)


def _feed(core: Estimator, tracker: StatusTracker, k: int, now_s: float) -> None:
    """Twist, steering and IMU of step ``k`` arriving at steady time ``now_s``."""
    stamp = T0_NS + k * STEP_NS
    for topic in TOPICS:
        tracker.received(topic, now_s)
    core.on_twist(TWIST, TwistFields(stamp, 20.0, 0.5))
    core.on_steering(STEERING, SteeringFields(stamp, 0.01, 0.0))
    tracker.imu_received(stamp, now_s)
    out = core.on_imu(IMU, ImuFields(stamp, 0.1, 2.0, 0.1))
    if out is not None:
        tracker.published(1e-4, out.estimate.variance_rad2)


def test_a_frame_mismatch_is_logged_once_per_topic_and_warned_while_it_lasts() -> None:
    tracker = _tracker(_core())
    line = "/vehicle/imu: frame_id 'imu_link', expected 'base_link' (used as if base_link)"
    assert tracker.frame_mismatch(IMU, "base_link") is None
    assert tracker.frame_mismatch(IMU, "imu_link") == line
    assert tracker.frame_mismatch(IMU, "imu_link") is None  # logged already
    assert tracker.frame_mismatch(TWIST, "odom") is not None  # another topic: its own log
    obs = tracker.observe(_core(), {}, [], now_s=1.0)
    assert obs.wrong_frames[0] == line and len(obs.wrong_frames) == 2
    assert _assess(obs).level == DIAGNOSTIC_WARN
    # The status says what the latest message carried: another wrong frame is named...
    assert tracker.frame_mismatch(IMU, "map") is None  # ...but not logged again
    assert "frame_id 'map'" in tracker.observe(_core(), {}, [], now_s=2.0).wrong_frames[0]
    # ...and the warning ends when the topics carry the contract's frame again.
    assert tracker.frame_mismatch(IMU, "base_link") is None
    assert tracker.frame_mismatch(TWIST, "base_link") is None
    assert tracker.observe(_core(), {}, [], now_s=3.0).wrong_frames == []
    assert tracker.frame_mismatch(IMU, "imu_link") is None  # logged once per topic, ever


def test_an_empty_frame_id_parameter_turns_the_frame_check_off() -> None:
    tracker = _tracker(_core(), frame_id="")
    assert tracker.frame_mismatch(IMU, "imu_link") is None
    assert tracker.frame_mismatch(TWIST, "") is None
    assert tracker.observe(_core(), {}, [], now_s=1.0).wrong_frames == []


def test_rejection_logs_are_throttled_to_one_per_log_every_s_per_reason() -> None:
    tracker = _tracker(_core())
    t0 = 1000.0
    assert tracker.rejection_due("non_finite", t0)
    assert not tracker.rejection_due("non_finite", t0 + 0.001)
    assert tracker.rejection_due("stale_twist", t0 + 0.002)  # another reason: its own clock
    assert not tracker.rejection_due("non_finite", t0 + LOG_EVERY_S - 0.001)
    assert tracker.rejection_due("non_finite", t0 + LOG_EVERY_S)
    # Measured from the last log, not from the last rejection.
    assert not tracker.rejection_due("non_finite", t0 + 2 * LOG_EVERY_S - 0.001)
    assert tracker.rejection_due("non_finite", t0 + 2 * LOG_EVERY_S)


def test_the_first_rejection_is_logged_whatever_the_steady_clock_reads() -> None:
    # time.monotonic() may be small (shortly after boot) or very large.
    for now_s in (0.0, 0.5, 1e7):
        assert _tracker(_core()).rejection_due("non_finite", now_s)


@given(gaps=st.lists(st.floats(0.0, 3 * LOG_EVERY_S, allow_nan=False), min_size=1, max_size=40))
def test_logged_rejections_are_log_every_s_apart_and_none_is_missed(gaps: list[float]) -> None:
    times = [100.0 + sum(gaps[: i + 1]) for i in range(len(gaps))]
    tracker = _tracker(_core())
    logged = [t for t in times if tracker.rejection_due("late_stamp", t)]
    assert logged and logged[0] == times[0]
    assert all(b - a >= LOG_EVERY_S for a, b in itertools.pairwise(logged))
    # A rejection goes unlogged only within LOG_EVERY_S of the previous log.
    for t in times:
        if t not in logged:
            assert t - max(x for x in logged if x <= t) < LOG_EVERY_S


def test_each_wrong_type_line_is_new_once() -> None:
    tracker = _tracker(_core())
    a = "/vehicle/imu: /echo publishes std_msgs/msg/String, expected sensor_msgs/msg/Imu"
    b = "/vehicle/twist: /echo publishes std_msgs/msg/String, expected ..."
    assert tracker.new_wrong_types([a, a]) == [a]
    assert tracker.new_wrong_types([a, b]) == [b]
    assert tracker.new_wrong_types([b, a]) == []


def test_the_status_stamp_is_the_ros_time_when_there_is_one() -> None:
    tracker = _tracker(_core())
    tracker.imu_received(T0_NS, 50.0)
    assert tracker.stamp_ns(T0_NS + 7, now_s=99.0, wall_ns=5) == T0_NS + 7


def test_with_sim_time_and_no_clock_the_status_stamp_still_advances() -> None:
    # use_sim_time with nothing on /clock: the ROS time reads 0.
    tracker = _tracker(_core())
    wall_ns = 1_750_000_000 * 10**9
    assert tracker.stamp_ns(0, now_s=49.0, wall_ns=wall_ns) == wall_ns  # no IMU yet
    tracker.imu_received(T0_NS, 50.0)
    first = tracker.stamp_ns(0, now_s=50.25, wall_ns=wall_ns)
    second = tracker.stamp_ns(0, now_s=50.75, wall_ns=wall_ns)
    assert first == T0_NS + 250_000_000  # the newest IMU stamp plus the time since
    assert second - first == 500_000_000


def test_observe_reports_ages_latencies_sigmas_and_what_happened_since_the_previous_call() -> None:
    core = _core()
    tracker = _tracker(core)
    for k in range(WINDOW + 4):  # 5 estimates once the window holds WINDOW samples
        _feed(core, tracker, k, now_s=10.0 + 0.0025 * k)
    with pytest.raises(InputRejected, match=r"linear_acceleration\.x is nan"):
        core.on_imu(IMU, ImuFields(T0_NS + 14 * STEP_NS, math.nan, 2.0, 0.1))
    tracker.received(IMU, 10.04)
    publishers = {IMU: ["/sim"], TWIST: ["/sim"], STEERING: ["/sim"]}
    obs = tracker.observe(core, publishers, [], now_s=10.05)

    assert obs.input_ages_s[IMU] == pytest.approx(0.01)
    assert obs.input_ages_s[TWIST] == pytest.approx(0.05 - 0.0025 * 13)
    assert obs.window_fill == (WINDOW, WINDOW)
    assert obs.new == Counts(rejections=1, estimates=5)
    assert obs.latencies_s == [1e-4] * 5
    assert len(obs.sigmas_rad) == 5
    assert all(s >= 0.0 and math.isfinite(s) for s in obs.sigmas_rad)
    assert obs.publishers == publishers and obs.silence_timeout_s == 0.1
    assert _assess(obs, core.stats).values["estimates"] == "5"

    tracker.published(2e-4, 4e-6)  # one more estimate, in the next period
    assert obs.latencies_s == [1e-4] * 5, "the reported period must not change afterwards"
    later = tracker.observe(core, publishers, [], now_s=11.0)
    assert later.new == Counts()  # the counters did not move since
    assert later.latencies_s == [2e-4] and later.sigmas_rad == [pytest.approx(2e-3)]
    assert later.input_ages_s[IMU] == pytest.approx(0.96)


def test_an_input_never_heard_from_has_no_age() -> None:
    core = _core()
    tracker = _tracker(core)
    tracker.received(IMU, 3.0)
    obs = tracker.observe(core, {}, [], now_s=3.5)
    assert obs.input_ages_s == {IMU: 0.5, TWIST: None, STEERING: None}
    assert "no message yet on /vehicle/twist, /vehicle/steering" in _assess(obs).message


def test_the_first_observation_counts_only_what_happened_after_the_tracker_started() -> None:
    core = _core()
    for k in range(WINDOW + 2):  # 3 estimates before the tracker exists
        _feed(core, _tracker(core), k, now_s=1.0)
    tracker = _tracker(core)
    _feed(core, tracker, WINDOW + 2, now_s=2.0)
    assert tracker.observe(core, {}, [], now_s=2.0).new == Counts(estimates=1)
