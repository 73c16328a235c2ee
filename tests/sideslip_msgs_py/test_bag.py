"""Bag writing and reading: real rosbag2 directories and MCAP files in tmp_path."""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from sideslip_msgs_py import qos, topics
from sideslip_msgs_py.bag import RUN_METADATA_KEY, open_raw_bag, read_bag, write_bag
from sideslip_msgs_py.errors import (
    BagError,
    BagExistsError,
    MissingTopicError,
    NotABagError,
    WrongTopicTypeError,
)
from sideslip_msgs_py.messages import TypestoreMessages, sample_to_messages
from sideslip_msgs_py.sample import SampleArrays, SensorNoiseSigma

JAZZY = get_typestore(Stores.ROS2_JAZZY)
MakeArrays = Callable[..., SampleArrays]


def _head(arrays: SampleArrays, n: int) -> SampleArrays:
    cols = {k: (None if v is None else v[:n]) for k, v in vars(arrays).items()}
    return SampleArrays(**cols)


def _write_raw_bag(path: Path, messages: Iterable[tuple[str, str, int, bytes]]) -> Path:
    """A bag with arbitrary (topic, type, stamp, cdr bytes) records, for refusal cases."""
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns: dict[tuple[str, str], Any] = {}
        for topic, msgtype, stamp, raw in messages:
            key = (topic, msgtype)
            if key not in conns:
                conns[key] = writer.add_connection(topic, msgtype, typestore=JAZZY)
            writer.write(conns[key], stamp, raw)
    return path


def _sample_records(arrays: SampleArrays, keep: set[str]) -> list[tuple[str, str, int, bytes]]:
    factory = TypestoreMessages(JAZZY)
    out = []
    for i in range(len(arrays)):
        sample = arrays.row(i)
        for topic, msg in sample_to_messages(sample, factory, SensorNoiseSigma.none()).items():
            if topic in keep:
                raw = bytes(JAZZY.serialize_cdr(msg, msg.__msgtype__))
                out.append((topic, msg.__msgtype__, sample.stamp_ns, raw))
    return out


def test_written_bag_reads_back_equal_arrays_and_run_metadata(
    small_bag: tuple[Path, SampleArrays], run_metadata: dict[str, object]
) -> None:
    path, arrays = small_bag
    contents = read_bag(path)
    assert contents.samples == arrays
    assert contents.run_metadata == run_metadata
    assert contents.topic_counts == dict.fromkeys(topics.SAMPLE_TOPICS, len(arrays))
    assert (contents.truncated, contents.notes) == (False, ())


@pytest.mark.parametrize("compress", [True, False])
def test_bag_without_truth_reads_back_without_truth(
    tmp_path: Path, make_arrays: MakeArrays, compress: bool
) -> None:
    arrays = make_arrays(50, truth=False)
    path = write_bag(
        tmp_path / "b", arrays, sigma=SensorNoiseSigma.none(), run_metadata={}, compress=compress
    )
    contents = read_bag(path)
    assert contents.samples == arrays
    assert not contents.samples.has_truth
    assert set(contents.topic_counts) == set(topics.SENSOR_TOPICS)


def test_metadata_yaml_is_a_jazzy_mcap_bag_with_qos_and_run_json(
    small_bag: tuple[Path, SampleArrays], run_metadata: dict[str, object]
) -> None:
    path, arrays = small_bag
    info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert (info["version"], info["storage_identifier"]) == (9, "mcap")
    assert info["relative_file_paths"] == ["run.mcap"]
    assert json.loads(info["custom_data"][RUN_METADATA_KEY]) == run_metadata
    by_topic = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert set(by_topic) == set(topics.SAMPLE_TOPICS)
    for topic, entry in by_topic.items():
        assert entry["message_count"] == len(arrays)
        assert entry["topic_metadata"]["type"] == topics.TOPIC_TYPES[topic]
        assert entry["topic_metadata"]["offered_qos_profiles"] == [
            qos.qos_for(topic).to_rosbag2_dict()
        ]


def test_bag_opens_in_anyreader_with_equal_counts_and_stamps_per_step(
    small_bag: tuple[Path, SampleArrays],
) -> None:
    path, arrays = small_bag
    stamps: dict[str, list[int]] = {t: [] for t in topics.SAMPLE_TOPICS}
    log_times: dict[str, list[int]] = {t: [] for t in topics.SAMPLE_TOPICS}
    with AnyReader([path], default_typestore=JAZZY) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == {
            t: topics.TOPIC_TYPES[t] for t in topics.SAMPLE_TOPICS
        }
        for conn in reader.connections:
            assert conn.msgcount == len(arrays)
            assert conn.ext.offered_qos_profiles == [qos.qos_for(conn.topic).to_rosbags()]
        for conn, log_time, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            log_times[conn.topic].append(log_time)
            if hasattr(msg, "header"):
                stamp = msg.header.stamp
                stamps[conn.topic].append(stamp.sec * 10**9 + stamp.nanosec)
                assert msg.header.frame_id == "base_link"
    expected = arrays.stamp_ns.tolist()
    for topic in topics.SAMPLE_TOPICS:
        assert log_times[topic] == expected, topic
        if topic != topics.GROUND_TRUTH_SIDESLIP:  # Float64 has no header
            assert stamps[topic] == expected, topic


def test_ground_truth_sideslip_equals_atan2_of_ground_truth_twist(
    small_bag: tuple[Path, SampleArrays],
) -> None:
    path, _ = small_bag
    twist: dict[int, tuple[float, float]] = {}
    beta: dict[int, float] = {}
    with AnyReader([path], default_typestore=JAZZY) as reader:
        wanted = [c for c in reader.connections if c.topic in topics.GROUND_TRUTH_TOPICS]
        for conn, log_time, raw in reader.messages(connections=wanted):
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == topics.GROUND_TRUTH_TWIST:
                twist[log_time] = (msg.twist.linear.x, msg.twist.linear.y)
            else:
                beta[log_time] = msg.data
    assert twist.keys() == beta.keys() and len(beta) > 0
    assert all(beta[t] == math.atan2(vy, vx) for t, (vx, vy) in twist.items())
    assert any(b != 0.0 for b in beta.values())


def test_bare_mcap_file_reads_like_its_directory(
    small_bag: tuple[Path, SampleArrays], tmp_path: Path, run_metadata: dict[str, object]
) -> None:
    path, arrays = small_bag
    bare = shutil.copy(path / "run.mcap", tmp_path / "copied.mcap")
    contents = read_bag(bare)
    assert contents.samples == arrays
    assert contents.run_metadata == run_metadata  # from the mcap's rosbag2 metadata record
    assert not contents.truncated


@pytest.mark.parametrize("compress", [True, False])
def test_truncated_mcap_yields_its_readable_prefix_and_says_so(
    tmp_path: Path, make_arrays: MakeArrays, compress: bool
) -> None:
    arrays = make_arrays(4000)  # several 1-MiB chunks
    path = write_bag(
        tmp_path / "b", arrays, sigma=SensorNoiseSigma.paper(), run_metadata={}, compress=compress
    )
    mcap = path / "b.mcap"
    data = mcap.read_bytes()
    bare = tmp_path / "cut.mcap"
    bare.write_bytes(data[: int(len(data) * 0.6)])

    contents = read_bag(bare)
    assert contents.truncated
    assert any(str(bare) in note and "unreadable after" in note for note in contents.notes)
    n = len(contents.samples)
    assert 0 < n < len(arrays)
    assert contents.samples == _head(arrays, n)


def test_bag_cut_inside_its_summary_loses_no_sample(
    small_bag: tuple[Path, SampleArrays], run_metadata: dict[str, object]
) -> None:
    path, arrays = small_bag
    mcap = path / "run.mcap"
    mcap.write_bytes(mcap.read_bytes()[:-20])
    contents = read_bag(path)
    assert contents.truncated
    assert contents.samples == arrays
    assert contents.run_metadata == run_metadata  # still in metadata.yaml


def test_damaged_chunk_behind_an_intact_summary_yields_the_chunks_before_it(
    tmp_path: Path, make_arrays: MakeArrays
) -> None:
    from mcap.reader import make_reader

    arrays = make_arrays(4000)  # several 1-MiB chunks
    path = write_bag(tmp_path / "b", arrays, sigma=SensorNoiseSigma.paper(), run_metadata={"a": 1})
    mcap = path / "b.mcap"
    with mcap.open("rb") as stream:
        second = make_reader(stream).get_summary().chunk_indexes[1]
    data = bytearray(mcap.read_bytes())
    start = second.chunk_start_offset + 53  # the second chunk's zstd frame, from its magic
    data[start : start + 400] = bytes(b ^ 0xA5 for b in data[start : start + 400])
    mcap.write_bytes(bytes(data))

    contents = read_bag(path)
    assert contents.truncated
    assert any("unreadable after" in note for note in contents.notes)
    n = len(contents.samples)
    assert 0 < n < len(arrays)
    assert contents.samples == _head(arrays, n)
    assert contents.run_metadata == {"a": 1}


def test_raw_reader_gives_topics_with_qos_and_repeatable_log_time_ordered_passes(
    small_bag: tuple[Path, SampleArrays],
) -> None:
    path, arrays = small_bag
    raw = open_raw_bag(path)
    assert (raw.truncated, raw.notes) == (False, ())
    assert set(raw.topics) == set(topics.SAMPLE_TOPICS)
    for name, topic in raw.topics.items():
        assert (topic.msgtype, topic.count) == (topics.TOPIC_TYPES[name], len(arrays))
        assert topic.offered_qos == (qos.qos_for(name).to_rosbags(),)
    assert (raw.start_ns, raw.end_ns) == (arrays.stamp_ns[0], arrays.stamp_ns[-1])
    imu = list(raw.messages([topics.IMU]))
    assert [m.log_time_ns for m in imu] == arrays.stamp_ns.tolist()
    assert list(raw.messages([topics.IMU])) == imu
    assert len(list(raw.messages())) == len(arrays) * len(topics.SAMPLE_TOPICS)


def test_existing_output_is_refused_without_force_and_replaced_with_it(
    small_bag: tuple[Path, SampleArrays], make_arrays: MakeArrays
) -> None:
    path, _ = small_bag
    other = make_arrays(10, seed=3)
    with pytest.raises(BagExistsError, match=str(path)):
        write_bag(path, other, sigma=SensorNoiseSigma.none(), run_metadata={})
    write_bag(path, other, sigma=SensorNoiseSigma.none(), run_metadata={"v": 2}, force=True)
    contents = read_bag(path)
    assert contents.samples == other
    assert contents.run_metadata == {"v": 2}


def test_force_never_deletes_a_directory_that_is_not_a_bag(
    tmp_path: Path, make_arrays: MakeArrays
) -> None:
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(BagExistsError, match="not part of a bag"):
        write_bag(
            tmp_path, make_arrays(5), sigma=SensorNoiseSigma.none(), run_metadata={}, force=True
        )
    assert (tmp_path / "notes.txt").exists()


def test_run_metadata_that_is_not_json_is_refused_before_writing(
    tmp_path: Path, make_arrays: MakeArrays
) -> None:
    with pytest.raises(BagError, match="run_metadata"):
        write_bag(
            tmp_path / "b",
            make_arrays(5),
            sigma=SensorNoiseSigma.none(),
            run_metadata={"x": {1, 2}},
        )
    assert not (tmp_path / "b").exists()


def test_missing_sensor_topic_is_refused_naming_bag_and_topic(
    tmp_path: Path, make_arrays: MakeArrays
) -> None:
    records = _sample_records(make_arrays(5), {topics.IMU, topics.TWIST})
    path = _write_raw_bag(tmp_path / "nosteer", records)
    with pytest.raises(MissingTopicError, match=rf"{path}.*/vehicle/steering"):
        read_bag(path)


def test_wrong_type_on_a_contract_topic_is_refused(tmp_path: Path, make_arrays: MakeArrays) -> None:
    records = _sample_records(make_arrays(5), {topics.IMU, topics.STEERING})
    twist_type = "geometry_msgs/msg/Twist"
    Twist, Vector3 = JAZZY.types[twist_type], JAZZY.types["geometry_msgs/msg/Vector3"]
    zero = Vector3(x=0.0, y=0.0, z=0.0)
    raw = bytes(JAZZY.serialize_cdr(Twist(linear=zero, angular=zero), twist_type))
    records.append((topics.TWIST, twist_type, 0, raw))
    path = _write_raw_bag(tmp_path / "wrongtype", records)
    with pytest.raises(WrongTopicTypeError, match=rf"{path}.*/vehicle/twist.*'{twist_type}'"):
        read_bag(path)


def test_paths_that_are_not_bags_are_refused(tmp_path: Path) -> None:
    text = tmp_path / "x.mcap"
    text.write_text("hello")
    with pytest.raises(NotABagError, match=r"x\.mcap"):
        read_bag(text)
    with pytest.raises(NotABagError, match=r"no metadata\.yaml"):
        read_bag(tmp_path)
    with pytest.raises(NotABagError, match="no such bag"):
        read_bag(tmp_path / "absent")


def test_slower_topics_align_to_the_latest_message_at_or_before_each_imu_stamp(
    tmp_path: Path, make_arrays: MakeArrays
) -> None:
    # IMU at 400 Hz, twist and steering at 100 Hz, starting one IMU step late.
    arrays = make_arrays(41, truth=False)
    imu = _sample_records(arrays, {topics.IMU})
    slow = _head(arrays, 41)
    others = [r for r in _sample_records(slow, {topics.TWIST, topics.STEERING})]
    step = int(arrays.stamp_ns[1] - arrays.stamp_ns[0])
    others = [r for r in others if (r[2] // step) % 4 == 1]
    path = _write_raw_bag(tmp_path / "rates", sorted(imu + others, key=lambda r: r[2]))

    contents = read_bag(path)
    assert len(contents.samples) == 40  # IMU message 0 predates every twist
    assert any("before the first /vehicle/twist" in note for note in contents.notes)
    source = (np.arange(1, 41) - 1) // 4 * 4 + 1  # index of the latest 100 Hz message
    np.testing.assert_array_equal(contents.samples.x_v_mps, arrays.x_v_mps[source])
    np.testing.assert_array_equal(contents.samples.stl_m, arrays.stl_m[source])
    np.testing.assert_array_equal(contents.samples.x_a_mps2, arrays.x_a_mps2[1:])


def test_rclpy_serialised_bag_with_fast_cdr_padding_reads(
    tmp_path: Path, make_arrays: MakeArrays
) -> None:
    from rclpy.serialization import serialize_message

    from sideslip_msgs_py.messages import RclpyMessages

    arrays = make_arrays(20)
    factory = RclpyMessages()
    records = []
    for i in range(len(arrays)):
        sample = arrays.row(i)
        for topic, msg in sample_to_messages(sample, factory, SensorNoiseSigma.paper()).items():
            raw = serialize_message(msg)
            if topic == topics.STEERING:  # also force the per-message path: another joint
                msg.name = ["steering_rack", "wheel_fl"]
                msg.position = [sample.stl_m, 0.0]
                msg.velocity = [sample.stl_rate_mps, 0.0]
                raw = serialize_message(msg)
            records.append((topic, topics.TOPIC_TYPES[topic], sample.stamp_ns, raw))
    contents = read_bag(_write_raw_bag(tmp_path / "rclpy", records))
    assert contents.samples == arrays
