"""sideslip-record: QoS adaptation, the bag it writes, refusals; then real DDS runs."""

from __future__ import annotations

import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml
from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from ros_support import BIN, wait_for
from rosbags.rosbag2 import Reader

from sideslip_bags import record
from sideslip_bags.bagsink import open_sink
from sideslip_bags.offered_qos import RECORD_DEPTH, OfferedQos, subscription_qos
from sideslip_msgs_py import topics
from sideslip_msgs_py.bag import read_bag, write_bag
from sideslip_msgs_py.sample import SampleArrays, SensorNoiseSigma

T0_NS = 1_700_000_000 * 10**9
STEP_NS = 2_500_000  # 400 Hz


def sample_bag(path: Path, n: int, *, seed: int = 0) -> Path:
    """A bag of ``n`` noisy 400-Hz samples on all five sample topics (not physics)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * (STEP_NS * 1e-9)
    arrays = SampleArrays(
        stamp_ns=T0_NS + np.arange(n, dtype=np.int64) * STEP_NS,
        x_v_mps=20.0 + rng.normal(0, 0.28, n),
        y_v_mps=0.8 * np.sin(np.pi * t) + rng.normal(0, 0.28, n),
        x_a_mps2=rng.normal(0, 0.1, n),
        y_a_mps2=rng.normal(0, 0.1, n),
        yaw_rate_radps=rng.normal(0, 0.0035, n),
        stl_m=0.02 * np.sin(np.pi * t),
        stl_rate_mps=0.02 * np.pi * np.cos(np.pi * t),
        truth_v_x_mps=np.full(n, 20.0),
        truth_v_y_mps=0.8 * np.sin(np.pi * t),
        truth_yaw_rate_radps=np.zeros(n),
    )
    return write_bag(path, arrays, sigma=SensorNoiseSigma.paper(), run_metadata={"seed": seed})


def topic_metadata(bag: Path) -> dict[str, dict]:
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    return {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}


# --- pure helpers ----------------------------------------------------------------------------


def offered(reliability: ReliabilityPolicy, durability=DurabilityPolicy.VOLATILE) -> OfferedQos:
    return OfferedQos.from_rclpy(
        QoSProfile(depth=5, reliability=reliability, durability=durability)
    )


def test_subscription_is_reliable_only_when_every_publisher_offers_reliable() -> None:
    reliable = offered(ReliabilityPolicy.RELIABLE)
    best_effort = offered(ReliabilityPolicy.BEST_EFFORT)
    assert subscription_qos([reliable, reliable]).reliability == "reliable"
    assert subscription_qos([reliable, best_effort]).reliability == "best_effort"
    assert subscription_qos([best_effort]).reliability == "best_effort"
    latched = offered(ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL)
    assert subscription_qos([latched]).durability == "transient_local"
    assert subscription_qos([latched, reliable]).durability == "volatile"
    assert subscription_qos([reliable]).depth == RECORD_DEPTH


def test_offered_qos_from_the_graph_is_stored_as_ros2_bag_record_writes_it() -> None:
    profile = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
    profile.deadline = Duration(nanoseconds=2**63 - 1)  # "infinite", as discovery reports it
    stored = OfferedQos.from_rclpy(profile).to_rosbags()
    assert (stored.deadline.sec, stored.deadline.nsec) == (9223372036, 854775807)
    assert stored.reliability.name == "BEST_EFFORT"
    assert OfferedQos.from_rosbags(stored) == OfferedQos.from_rclpy(profile)
    sensor = OfferedQos.from_rclpy(qos_profile_sensor_data)
    assert (sensor.reliability, sensor.history, sensor.depth) == ("best_effort", "keep_last", 5)


def test_sink_writes_bytes_verbatim_with_offered_qos_into_a_jazzy_mcap_bag(tmp_path: Path) -> None:
    source = sample_bag(tmp_path / "src", 50)
    sink = open_sink(tmp_path / "out")
    offers = [offered(ReliabilityPolicy.BEST_EFFORT)]
    with Reader(source) as reader:
        for conn in reader.connections:
            sink.add_topic(conn.topic, conn.msgtype, offers)
        expected = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
    for topic, t, data in expected:
        sink.write(topic, t, data)
    sink.close()
    sink.close()  # idempotent

    with Reader(tmp_path / "out") as reader:
        assert [(c.topic, t, bytes(d)) for c, t, d in reader.messages()] == expected
    meta = topic_metadata(tmp_path / "out")
    imu = meta[topics.IMU]["topic_metadata"]
    assert imu["offered_qos_profiles"][0]["reliability"] == "best_effort"
    assert (imu["type"], imu["serialization_format"]) == (topics.IMU_TYPE, "cdr")
    assert imu["type_description_hash"].startswith("RIHS01_")
    info = yaml.safe_load((tmp_path / "out" / "metadata.yaml").read_text())
    info = info["rosbag2_bagfile_information"]
    assert (info["version"], info["storage_identifier"]) == (9, "mcap")
    assert read_bag(tmp_path / "out").samples == read_bag(source).samples


def test_flushed_messages_survive_a_recorder_that_never_closes(tmp_path: Path) -> None:
    source = sample_bag(tmp_path / "src", 200)
    sink = open_sink(tmp_path / "out")
    with Reader(source) as reader:
        for conn in reader.connections:
            sink.add_topic(conn.topic, conn.msgtype, [])
        for conn, t, data in reader.messages():
            sink.write(conn.topic, t, data)
    sink.flush()  # then "killed": no close, no summary, only the provisional metadata.yaml
    contents = read_bag(tmp_path / "out" / "out.mcap")
    assert contents.truncated
    assert len(contents.samples) == 200
    assert read_bag(tmp_path / "out").samples == contents.samples  # the directory too


# --- command line refusals -------------------------------------------------------------------


def test_existing_out_is_refused_without_force_in_one_line_with_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = sample_bag(tmp_path / "out", 4)
    assert record.main(["--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--force" in err and str(out) in err
    # The console script says the same and exits 2 (nothing is started).
    done = subprocess.run(
        [str(BIN / "sideslip-record"), "--out", str(out), "--topics", topics.IMU],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and done.stdout == ""


@pytest.mark.parametrize(
    ("args", "names"),
    [
        (["--topics", "/vehicle/nope"], "/vehicle/nope"),
        (["--max-duration", "0"], "--max-duration"),
    ],
)
def test_bad_input_is_one_line_naming_it_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], names: str
) -> None:
    assert record.main(["--out", str(tmp_path / "rec"), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("sideslip-record: error:") and names in err
    assert not (tmp_path / "rec").exists()


# --- real DDS ---------------------------------------------------------------------------------


def mcap_size(bag: Path) -> int:
    mcap = bag / f"{bag.name}.mcap"
    return mcap.stat().st_size if mcap.exists() else 0


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_mid_stream_stops_within_2_s_and_leaves_a_whole_bag(spawn, scratch_dir, sig):
    bag = sample_bag(scratch_dir / "src", 4000)  # 10 s: still playing when the signal comes
    out = scratch_dir / "rec"
    recorder = spawn("sideslip-record", "--out", str(out))
    spawn("sideslip-play", str(bag))  # with the bag's best-effort QoS
    # The recorder writes a chunk to the file once a second: data is flowing into it.
    wait_for(lambda: mcap_size(out) > 4096, 20, "recorded messages on disk")
    code, seconds = recorder.stop(sig)
    assert code == 0, recorder.output()
    assert seconds < 2.0
    contents = read_bag(out)
    assert not contents.truncated and len(contents.samples) > 0
    assert set(contents.topic_counts) == set(topics.SAMPLE_TOPICS)
    with Reader(out) as reader:  # rosbags reads it whole too
        assert sum(1 for _ in reader.messages()) == sum(contents.topic_counts.values())
    # Best-effort publishers: a best-effort subscription, and the offers are in the bag.
    offer = topic_metadata(out)[topics.IMU]["topic_metadata"]["offered_qos_profiles"][0]
    assert offer["reliability"] == "best_effort"
    log = recorder.output()
    assert f"recording {topics.IMU} ({topics.IMU_TYPE}, best_effort" in log
    assert f"recorded {sum(contents.topic_counts.values())} messages" in log


def test_max_duration_stops_by_itself_with_an_empty_but_valid_bag(spawn, scratch_dir):
    out = scratch_dir / "rec"
    recorder = spawn("sideslip-record", "--out", str(out), "--max-duration", "0.5")
    assert recorder.proc.wait(30) == 0, recorder.output()
    with Reader(out) as reader:
        assert reader.message_count == 0
    assert "recorded 0 messages" in recorder.output()
