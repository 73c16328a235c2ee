"""The status diagnostic: OK while estimating, WARN when degraded, ERROR for unusable input,
with a one-line message and the values an operator reads."""

from __future__ import annotations

from collections import Counter
from dataclasses import replace

import pytest

from sideslip_estimator.estimator import EstimatorStats
from sideslip_estimator.status import LEVEL_NAMES, Counts, Observation, Status, assess
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
    import math

    v = _assess(_obs(sigmas_rad=[math.radians(0.05)] * 19 + [math.radians(0.5)])).values
    assert v["beta_sigma_deg_p50"] == "0.0500" and float(v["beta_sigma_deg_p95"]) > 0.05
    assert _assess(_obs()).values["beta_sigma_deg_p50"] == "n/a"
