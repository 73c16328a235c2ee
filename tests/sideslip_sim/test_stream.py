"""What the sim node publishes, without ROS: the runs a scenario names, and a stream of
samples equal to a generated bag's, on one continuous time line."""

from __future__ import annotations

import itertools
import time
from pathlib import Path

import numpy as np
import pytest

from sideslip_msgs_py import topics
from sideslip_msgs_py.bag import read_bag
from sideslip_msgs_py.messages import stamp_ns
from sideslip_msgs_py.sample import SENSOR_CHANNELS, TRUTH_CHANNELS, SampleArrays, SensorNoiseSigma
from sideslip_sim.generate import generate_run
from sideslip_sim.maneuvers import FAMILIES, SCENARIOS, Maneuver, ManeuverError
from sideslip_sim.presets import PRESETS, paper_test, paper_train, preset
from sideslip_sim.sensors import add_noise, exact_samples, run_seed
from sideslip_sim.simulate import simulate
from sideslip_sim.stream import DT_NS, RUN_PAUSE_S, ManeuverSpec, SampleStream, select_runs
from sideslip_sim.vehicle import load_vehicle

PAUSE_NS = round(RUN_PAUSE_S * 1e9)
ORIGIN_NS = 1_700_000_000 * 10**9
SHORT = ManeuverSpec(duration_s=1.0, speed_kmh=60.0, torque_nm=100.0)


@pytest.fixture(scope="module")
def vehicle():
    return load_vehicle("paper_sedan")


def _short_runs(n: int = 1) -> list[Maneuver]:
    families = ["sine_steer", "step_steer", "sweep_steer"]
    return [select_runs(f, seed=3, spec=SHORT)[0] for f in families[:n]]


def _channels(s: SampleArrays, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    return {n: getattr(s, n) for n in names}


def _assert_same_values(a: SampleArrays, b: SampleArrays) -> None:
    """Every sensor and truth channel equal bit for bit (stamps may differ)."""
    assert len(a) == len(b) and a.has_truth == b.has_truth
    names = SENSOR_CHANNELS + (TRUTH_CHANNELS if a.has_truth else ())
    for n in names:
        np.testing.assert_array_equal(getattr(a, n), getattr(b, n), err_msg=n)


# --- select_runs ------------------------------------------------------------------------------


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_a_table4_scenario_selects_its_paper_test_run(scenario: str) -> None:
    runs = select_runs(scenario)
    assert runs == [m for m in paper_test() if m.scenario == scenario]
    assert len(runs) == 1 and runs[0].name == scenario


def test_presets_select_their_runs() -> None:
    assert select_runs("paper-test") == paper_test()
    assert select_runs("paper-train") == paper_train()
    assert select_runs("randomized", seed=7, count=3) == preset("randomized", seed=7, count=3)
    assert select_runs("randomized", seed=8, count=3) != select_runs("randomized", seed=7, count=3)
    assert set(PRESETS) == {"paper-test", "paper-train", "randomized"}


@pytest.mark.parametrize("family", [f for f in FAMILIES if f != "scenario"])
def test_a_family_selects_one_run_built_from_the_spec(family: str) -> None:
    spec = ManeuverSpec(duration_s=7.5, speed_kmh=65.0, torque_nm=200.0,
                        stl_amplitude_m=0.05, mu=0.6)  # fmt: skip
    (run,) = select_runs(family, seed=11, spec=spec)
    assert run.family == family and run.name == f"{family}_v65"
    assert (run.duration_s, run.speed_kmh, run.torque_nm) == (7.5, 65.0, 200.0)
    assert (run.stl_amplitude_m, run.mu, run.seed) == (0.05, 0.6, 11)


def test_a_family_without_spec_uses_the_spec_defaults() -> None:
    (run,) = select_runs("sine_steer")
    d = ManeuverSpec()
    assert (run.duration_s, run.speed_kmh, run.torque_nm, run.mu) == (
        d.duration_s,
        d.speed_kmh,
        d.torque_nm,
        d.mu,
    )


@pytest.mark.parametrize("name", ["scen5", "scenario", "paper_test", ""])
def test_unknown_scenario_is_an_error_listing_the_choices(name: str) -> None:
    with pytest.raises(ManeuverError) as info:
        select_runs(name)
    msg = str(info.value)
    assert isinstance(info.value, ValueError) and repr(name) in msg
    for choice in (*SCENARIOS, *PRESETS, "sine_steer", "double_lane_change", "step_steer"):
        assert choice in msg
    assert "scenario," not in msg.split("families", 1)[1]  # not a family one can pick


# --- SampleStream -----------------------------------------------------------------------------


def test_stream_samples_equal_the_generated_bag_for_the_same_run_noise_and_seed(
    vehicle, tmp_path: Path
) -> None:
    (run,) = select_runs("sine_steer", seed=5, spec=SHORT)
    generate_run(vehicle, run, tmp_path, noise="paper", seed=5, preset_name="custom")
    bag = read_bag(tmp_path / run.name).samples
    stream = SampleStream(vehicle, [run], SensorNoiseSigma.paper(), seed=5, origin_ns=ORIGIN_NS)
    (chunk,) = list(stream)
    _assert_same_values(chunk.samples, bag)
    # ... which is the generator's path: simulate -> exact samples -> per-run noise.
    noisy = add_noise(
        exact_samples(simulate(vehicle, run)), SensorNoiseSigma.paper(), run_seed(5, run.name)
    )
    _assert_same_values(chunk.samples, noisy)
    np.testing.assert_array_equal(chunk.samples.stamp_ns - ORIGIN_NS, noisy.stamp_ns)


def test_another_seed_gives_other_noise_and_the_same_truth(vehicle) -> None:
    runs = _short_runs()
    a = next(iter(SampleStream(vehicle, runs, SensorNoiseSigma.paper(), seed=1, origin_ns=0)))
    b = next(iter(SampleStream(vehicle, runs, SensorNoiseSigma.paper(), seed=2, origin_ns=0)))
    assert not np.array_equal(a.samples.x_v_mps, b.samples.x_v_mps)
    np.testing.assert_array_equal(a.samples.truth_v_y_mps, b.samples.truth_v_y_mps)


def test_runs_follow_on_one_time_line_with_a_pause_between_them(vehicle) -> None:
    runs = _short_runs(3)
    chunks = list(SampleStream(vehicle, runs, SensorNoiseSigma.none(), seed=0, origin_ns=ORIGIN_NS))
    assert [c.maneuver for c in chunks] == runs
    assert chunks[0].samples.stamp_ns[0] == ORIGIN_NS
    for c in chunks:
        assert np.all(np.diff(c.samples.stamp_ns) == DT_NS)
    for prev, nxt in itertools.pairwise(chunks):
        assert nxt.samples.stamp_ns[0] - prev.samples.stamp_ns[-1] == PAUSE_NS


def test_pause_between_runs_is_longer_than_the_estimators_max_gap() -> None:
    from sideslip_estimator.estimator import EstimatorParams

    assert RUN_PAUSE_S > EstimatorParams().max_gap_s


def test_stream_without_origin_starts_at_the_wall_clock(vehicle) -> None:
    before = time.time_ns()
    chunk = next(iter(SampleStream(vehicle, _short_runs(), SensorNoiseSigma.none(), seed=0)))
    after = time.time_ns()
    assert before <= chunk.samples.stamp_ns[0] <= after


@pytest.mark.parametrize("k", [2, 4, 10])
def test_decimation_keeps_every_kth_sample(vehicle, k: int) -> None:
    runs = _short_runs(2)
    sigma = SensorNoiseSigma.paper()
    full = list(SampleStream(vehicle, runs, sigma, seed=4, origin_ns=ORIGIN_NS))
    dec = list(SampleStream(vehicle, runs, sigma, seed=4, origin_ns=ORIGIN_NS, decimation=k))
    for f, d in zip(full, dec, strict=True):
        for n in SENSOR_CHANNELS + TRUTH_CHANNELS:
            np.testing.assert_array_equal(getattr(d.samples, n), getattr(f.samples, n)[::k])
    np.testing.assert_array_equal(dec[0].samples.stamp_ns, full[0].samples.stamp_ns[::k])
    assert np.all(np.diff(dec[0].samples.stamp_ns) == k * DT_NS)
    last = ORIGIN_NS + (len(full[0].samples) - 1) // k * k * DT_NS
    assert dec[1].samples.stamp_ns[0] == last + PAUSE_NS


def test_without_ground_truth_the_truth_channels_and_topics_are_dropped(vehicle) -> None:
    stream = SampleStream(
        vehicle, _short_runs(), SensorNoiseSigma.paper(), seed=0, origin_ns=0, ground_truth=False
    )
    chunk = next(iter(stream))
    assert not chunk.samples.has_truth
    assert set(chunk.messages) == set(topics.SENSOR_TOPICS)


def test_messages_hold_one_cdr_row_per_sample_of_every_topic(vehicle) -> None:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    chunk = next(
        iter(SampleStream(vehicle, _short_runs(), SensorNoiseSigma.paper(), seed=0, origin_ns=0))
    )
    assert set(chunk.messages) == set(topics.SAMPLE_TOPICS)
    n = len(chunk.samples)
    for topic, rows in chunk.messages.items():
        assert rows.shape[0] == n
        msg = store.deserialize_cdr(rows[n // 2].tobytes(), topics.TOPIC_TYPES[topic])
        if topic != topics.GROUND_TRUTH_SIDESLIP:
            assert stamp_ns(msg) == chunk.samples.stamp_ns[n // 2]
    imu = store.deserialize_cdr(chunk.messages[topics.IMU][-1].tobytes(), topics.IMU_TYPE)
    assert imu.angular_velocity.z == chunk.samples.yaw_rate_radps[-1]


def test_loop_repeats_the_runs_on_a_continuing_time_line(vehicle) -> None:
    runs = _short_runs(2)
    stream = SampleStream(
        vehicle, runs, SensorNoiseSigma.paper(), seed=0, origin_ns=ORIGIN_NS, loop=True
    )
    chunks = list(itertools.islice(iter(stream), 5))
    assert [c.maneuver for c in chunks] == [*runs, *runs, runs[0]]
    _assert_same_values(chunks[0].samples, chunks[2].samples)
    _assert_same_values(chunks[1].samples, chunks[3].samples)
    for prev, nxt in itertools.pairwise(chunks):
        assert nxt.samples.stamp_ns[0] - prev.samples.stamp_ns[-1] == PAUSE_NS


def test_without_loop_the_stream_ends_after_the_last_run(vehicle) -> None:
    runs = _short_runs(2)
    stream = SampleStream(vehicle, runs, SensorNoiseSigma.none(), seed=0, origin_ns=0)
    assert [c.maneuver for c in stream] == runs


@pytest.mark.parametrize(
    ("runs", "decimation", "match"), [([], 1, "no runs"), (None, 0, "decimation")]
)
def test_stream_refuses_no_runs_and_bad_decimation(vehicle, runs, decimation, match) -> None:
    runs = _short_runs() if runs is None else runs
    with pytest.raises(ValueError, match=match):
        SampleStream(vehicle, runs, SensorNoiseSigma.none(), seed=0, decimation=decimation)
