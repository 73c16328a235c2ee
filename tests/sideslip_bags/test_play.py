"""sideslip-play: remaps, QoS from bag metadata, refusals; then real DDS runs."""

from __future__ import annotations

import signal
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import TwistStamped
from rclpy.qos import QoSProfile, ReliabilityPolicy
from ros_support import wait_for
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64

from sideslip_bags import play
from sideslip_bags.bagsink import open_sink
from sideslip_bags.bagsource import open_bag
from sideslip_bags.errors import OptionError, UnknownTypeError
from sideslip_bags.offered_qos import (
    INFINITE_NS,
    RELIABLE_PLAY_DEPTH,
    OfferedQos,
    parse_offered_qos_yaml,
    publisher_qos,
)
from sideslip_bags.options import parse_remaps, split_ros_args
from sideslip_bags.playplan import PlayOptions, plan_playback
from sideslip_msgs_py import qos, topics
from sideslip_msgs_py.bag import write_bag
from sideslip_msgs_py.errors import NotABagError
from sideslip_msgs_py.nodes.qos import profile_for
from sideslip_msgs_py.sample import SampleArrays, SensorNoiseSigma

T0_NS = 1_700_000_000 * 10**9
STEP_NS = 2_500_000  # 400 Hz
RELIABLE_DEEP = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)


def sample_bag(path: Path, n: int, *, seed: int = 0) -> Path:
    """A bag of ``n`` noisy 400-Hz samples on all five sample topics (not physics)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * (STEP_NS * 1e-9)
    v_y = 0.8 * np.sin(np.pi * t)
    arrays = SampleArrays(
        stamp_ns=T0_NS + np.arange(n, dtype=np.int64) * STEP_NS,
        x_v_mps=20.0 + rng.normal(0, 0.28, n),
        y_v_mps=v_y + rng.normal(0, 0.28, n),
        x_a_mps2=rng.normal(0, 0.1, n),
        y_a_mps2=rng.normal(0, 0.1, n),
        yaw_rate_radps=0.3 * np.sin(np.pi * t) + rng.normal(0, 0.0035, n),
        stl_m=0.02 * np.sin(np.pi * t),
        stl_rate_mps=0.02 * np.pi * np.cos(np.pi * t),
        truth_v_x_mps=np.full(n, 20.0),
        truth_v_y_mps=v_y,
        truth_yaw_rate_radps=0.3 * np.sin(np.pi * t),
    )
    return write_bag(path, arrays, sigma=SensorNoiseSigma.paper(), run_metadata={"seed": seed})


def raw_messages(bag: Path) -> dict[str, list[bytes]]:
    with Reader(bag) as reader:
        out: dict[str, list[bytes]] = {c.topic: [] for c in reader.connections}
        for conn, _, data in reader.messages():
            out[conn.topic].append(bytes(data))
    return out


# --- pure helpers ----------------------------------------------------------------------------


def test_remaps_parse_and_bad_syntax_names_the_item() -> None:
    assert parse_remaps(["/a:=/b", "/c:=/d"]) == {"/a": "/b", "/c": "/d"}
    for bad in ["/a", "/a:=", ":=/b", "/a:=/b:=/c", "/a:=/b c", "/a=/b"]:
        with pytest.raises(OptionError, match="--remap"):
            parse_remaps([bad])
    with pytest.raises(OptionError, match="already remapped"):
        parse_remaps(["/a:=/b", "/a:=/c"])


def test_ros_args_are_split_from_ours_as_rcl_does() -> None:
    argv = ["bag", "--rate", "2", "--ros-args", "-r", "__node:=p", "--", "--loop"]
    assert split_ros_args(argv) == (
        ["bag", "--rate", "2", "--loop"],
        ["--ros-args", "-r", "__node:=p"],
    )


def test_publisher_qos_keeps_agreed_offers_and_relaxes_disagreements() -> None:
    sensor = OfferedQos.from_rosbag2_dict(qos.SENSOR_DATA.to_rosbag2_dict())
    assert publisher_qos([sensor]) == qos.SENSOR_DATA
    discovered = OfferedQos(  # what DDS discovery reports: no history, infinite durations
        history="unknown",
        depth=0,
        reliability="reliable",
        durability="volatile",
        deadline_ns=INFINITE_NS,
        lifespan_ns=INFINITE_NS,
        liveliness="automatic",
        liveliness_lease_duration_ns=INFINITE_NS,
    )
    spec = publisher_qos([discovered])
    assert spec is not None
    assert (spec.reliability, spec.history, spec.depth) == ("reliable", "keep_last", 10)
    assert (spec.deadline_ns, spec.lifespan_ns, spec.liveliness) == (0, 0, "automatic")
    mixed = publisher_qos([discovered, sensor])
    assert mixed is not None
    assert (mixed.reliability, mixed.durability, mixed.depth) == ("best_effort", "volatile", 5)
    assert publisher_qos([]) is None


def test_offered_qos_reads_v8_integers_and_v9_names_alike() -> None:
    v9 = parse_offered_qos_yaml(
        "- history: keep_last\n  depth: 5\n  reliability: best_effort\n  durability: volatile\n"
        "  deadline:\n    sec: 9223372036\n    nsec: 854775807\n  liveliness: automatic\n"
    )
    v8 = parse_offered_qos_yaml(
        "- history: 1\n  depth: 5\n  reliability: 2\n  durability: 2\n"
        "  deadline:\n    sec: 9223372036\n    nsec: 854775807\n  liveliness: 1\n"
    )
    assert v8 == v9
    assert v9[0].deadline_ns == INFINITE_NS
    with pytest.raises(ValueError, match="reliability"):
        parse_offered_qos_yaml("- reliability: sometimes\n")


def test_plan_uses_bag_qos_then_contract_qos_and_reliable_overrides(tmp_path: Path) -> None:
    bag = sample_bag(tmp_path / "b", 10)
    plan = plan_playback(open_bag(bag), PlayOptions(bag))
    assert {t.bag_topic: t.qos for t in plan.topics} == dict.fromkeys(
        topics.SAMPLE_TOPICS, qos.SENSOR_DATA
    )
    plan = plan_playback(
        open_bag(bag),
        PlayOptions(bag, reliable=True, topics=(topics.IMU,), remaps=((topics.IMU, "/car"),)),
    )
    (only,) = plan.topics
    assert (only.out_topic, only.qos.reliability, only.qos.depth) == (
        "/car",
        "reliable",
        RELIABLE_PLAY_DEPTH,
    )
    # A bag without recorded QoS: contract topics get the contract QoS.
    bare = tmp_path / "noqos"
    with Writer(bare, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        from rosbags.typesys import Stores, get_typestore

        conn = writer.add_connection(
            topics.SIDESLIP, topics.FLOAT64_TYPE, typestore=get_typestore(Stores.ROS2_JAZZY)
        )
        writer.write(conn, T0_NS, b"\x00\x01\x00\x00" + bytes(8))
    (beta,) = plan_playback(open_bag(bare), PlayOptions(bare)).topics
    assert beta.qos == qos.RELIABLE


def test_plan_refuses_topics_and_remaps_that_the_bag_lacks(tmp_path: Path) -> None:
    bag = sample_bag(tmp_path / "b", 10)
    source = open_bag(bag)
    with pytest.raises(OptionError, match="/nope"):
        plan_playback(source, PlayOptions(bag, topics=("/nope",)))
    with pytest.raises(OptionError, match="/nope"):
        plan_playback(source, PlayOptions(bag, remaps=(("/nope", "/x"),)))


def test_plan_waits_for_the_named_published_topics_or_for_all(tmp_path: Path) -> None:
    bag = sample_bag(tmp_path / "b", 10)
    source = open_bag(bag)
    assert plan_playback(source, PlayOptions(bag)).wait_topics == ()
    waiting = plan_playback(source, PlayOptions(bag, wait_subscribers_s=5.0))
    assert sorted(waiting.wait_topics) == sorted(topics.SAMPLE_TOPICS)
    named = PlayOptions(
        bag,
        wait_subscribers_s=5.0,
        wait_topics=("/car/imu", topics.TWIST),
        remaps=((topics.IMU, "/car/imu"),),
    )
    assert plan_playback(source, named).wait_topics == ("/car/imu", topics.TWIST)


@pytest.mark.parametrize(
    ("options", "names"),
    [
        ({"wait_subscribers_s": 5.0, "wait_topics": ("/nope",)}, "--wait-topics /nope"),
        # Named by its bag name although --remap publishes it under another one.
        (
            {
                "wait_subscribers_s": 5.0,
                "wait_topics": (topics.IMU,),
                "remaps": ((topics.IMU, "/car/imu"),),
            },
            f"--wait-topics {topics.IMU}",
        ),
        ({"wait_subscribers_s": 5.0, "wait_count": 0}, "--wait-count"),
        ({"wait_topics": (topics.IMU,)}, "--wait-subscribers"),
        ({"wait_count": 2}, "--wait-subscribers"),
    ],
)
def test_plan_refuses_wait_options_that_cannot_work(tmp_path: Path, options, names) -> None:
    bag = sample_bag(tmp_path / "b", 10)
    with pytest.raises(OptionError, match=names):
        plan_playback(open_bag(bag), PlayOptions(bag, **options))


def test_truncated_mcap_opens_with_its_readable_messages_in_log_time_order(
    tmp_path: Path,
) -> None:
    full = raw_messages(sample_bag(tmp_path / "b", 400))
    # Copy into a bag with small chunks (one per 200 messages), then cut it in the middle.
    sink = open_sink(tmp_path / "chunked", compress=True)
    for topic in topics.SAMPLE_TOPICS:
        sink.add_topic(topic, topics.TOPIC_TYPES[topic], [])
    for i in range(400):
        for topic in topics.SAMPLE_TOPICS:
            sink.write(topic, T0_NS + i * STEP_NS, full[topic][i])
        if i % 40 == 39:
            sink.flush()
    sink.close()
    data = (tmp_path / "chunked" / "chunked.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])

    source = open_bag(cut)
    assert source.truncated and any("unreadable after" in n for n in source.notes)
    got = list(source.messages(topics.SAMPLE_TOPICS))
    assert 0 < len(got) < 2000 and len(got) % 200 == 0  # whole chunks only
    assert [m.log_time_ns for m in got] == sorted(m.log_time_ns for m in got)
    imu = [m.data for m in got if m.topic == topics.IMU]
    assert imu == full[topics.IMU][: len(imu)]


def test_paths_that_are_not_bags_are_refused(tmp_path: Path) -> None:
    with pytest.raises(NotABagError, match="no such bag"):
        open_bag(tmp_path / "missing")
    (tmp_path / "dir").mkdir()
    with pytest.raises(NotABagError, match=r"metadata\.yaml"):
        open_bag(tmp_path / "dir")
    (tmp_path / "x.mcap").write_text("hello")
    with pytest.raises(NotABagError, match="magic"):
        open_bag(tmp_path / "x.mcap")


# --- command line refusals (in-process: they happen before rclpy starts) ---------------------


def unknown_type_bag(path: Path) -> Path:
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection(
            "/thing", "nonexistent_msgs/msg/Thing", msgdef="float64 x", rihs01="RIHS01_" + "0" * 64
        )
        writer.write(conn, T0_NS, b"\x00\x01\x00\x00" + bytes(8))
    return path


@pytest.mark.parametrize(
    ("args", "names"),
    [
        (["{missing}"], "no such bag"),
        (["{bag}", "--rate", "0"], "--rate"),
        (["{bag}", "--rate", "-2"], "--rate"),
        (["{bag}", "--remap", "/vehicle/imu=/x"], "--remap"),
        (["{bag}", "--topics", "/nope"], "/nope"),
        (["{bag}", "--clock", "0"], "--clock"),
        (["{unknown}"], "nonexistent_msgs/msg/Thing"),
        (["{bag}", "--wait-subscribers", "5", "--wait-topics", "/nope"], "--wait-topics /nope"),
        (["{bag}", "--wait-topics", "/vehicle/imu"], "--wait-subscribers"),
        (["{bag}", "--wait-subscribers", "-1"], "--wait-subscribers"),
    ],
)
def test_bad_input_is_one_line_naming_it_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], names: str
) -> None:
    paths = {
        "missing": tmp_path / "missing",
        "bag": sample_bag(tmp_path / "bag", 4),
        "unknown": unknown_type_bag(tmp_path / "unknown"),
    }
    assert play.main([a.format(**paths) for a in args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("sideslip-play: error:") and names in err


def test_unknown_type_error_names_type_and_package() -> None:
    from sideslip_bags.msgtypes import message_class

    assert message_class("std_msgs/msg/Float64") is Float64
    with pytest.raises(UnknownTypeError, match="nonexistent_msgs"):
        message_class("nonexistent_msgs/msg/Thing")


# --- real DDS ---------------------------------------------------------------------------------


def test_topics_filter_and_remap_publish_the_bag_bytes_on_the_new_name(spawn, probe, tmp_path):
    bag = sample_bag(tmp_path / "b", 200)
    expected = raw_messages(bag)
    car = probe.subscribe("/car/imu", Imu, RELIABLE_DEEP, raw=True)
    twist = probe.subscribe(topics.TWIST, TwistStamped, RELIABLE_DEEP, raw=True)
    imu = probe.subscribe(topics.IMU, Imu, RELIABLE_DEEP, raw=True)
    steering = probe.subscribe(topics.STEERING, JointState, RELIABLE_DEEP, raw=True)
    player = spawn(
        "sideslip-play", str(bag), "--topics", topics.IMU, topics.TWIST,
        "--remap", f"{topics.IMU}:=/car/imu", "--reliable", "--wait-subscribers", "20",
        "--rate", "4",
    )  # fmt: skip
    assert player.proc.wait(30) == 0, player.output()
    # --reliable and the player's wait for acknowledgements: every message has arrived.
    wait_for(lambda: len(car) == 200 and len(twist) == 200, 5, "all 200 messages")
    assert [r.msg for r in car] == expected[topics.IMU]
    assert [r.msg for r in twist] == expected[topics.TWIST]
    assert imu == [] and steering == []


def test_clock_publishes_bag_time_advancing_at_the_playback_rate(spawn, probe, tmp_path):
    bag = sample_bag(tmp_path / "b", 800)  # 2 s of bag time
    clock = probe.subscribe(topics.CLOCK, Clock, profile_for(topics.CLOCK))
    beta = probe.subscribe(topics.GROUND_TRUTH_SIDESLIP, Float64, profile_for(topics.IMU))
    player = spawn(
        "sideslip-play", str(bag), "--clock", "50", "--rate", "2",
        "--topics", topics.GROUND_TRUTH_SIDESLIP, "--wait-subscribers", "20",
    )  # fmt: skip
    assert player.proc.wait(30) == 0, player.output()
    assert beta, "the played topic arrived too"
    stamps = np.array([r.msg.clock.sec * 10**9 + r.msg.clock.nanosec for r in clock])
    recv = np.array([r.recv_ns for r in clock])
    assert stamps.size >= 20, f"{stamps.size} /clock messages in a 1-s playback at 50 Hz"
    assert np.all(np.diff(stamps) >= 0)
    last_ns = T0_NS + 799 * STEP_NS
    assert stamps.min() >= T0_NS and stamps.max() <= last_ns
    assert stamps.max() >= last_ns - 100_000_000  # 20 ms of wall time at rate 2 and 50 Hz
    # Bag time runs at twice the wall time (receive times jitter by a few ms).
    rate = (stamps[-1] - stamps[0]) / (recv[-1] - recv[0])
    assert rate == pytest.approx(2.0, rel=0.15)


def test_loop_repeats_the_bag_until_stopped(spawn, probe, tmp_path):
    bag = sample_bag(tmp_path / "b", 40)  # 0.1 s
    expected = raw_messages(bag)[topics.GROUND_TRUTH_SIDESLIP]
    beta = probe.subscribe(topics.GROUND_TRUTH_SIDESLIP, Float64, RELIABLE_DEEP, raw=True)
    player = spawn(
        "sideslip-play", str(bag), "--loop", "--reliable", "--wait-subscribers", "20",
        "--topics", topics.GROUND_TRUTH_SIDESLIP,
    )  # fmt: skip
    wait_for(lambda: len(beta) >= 100, 20, "more messages than the bag holds")
    code, seconds = player.stop(signal.SIGINT)
    assert code == 0 and seconds < 2.0, player.output()
    assert [r.msg for r in beta[:80]] == expected + expected


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_playback_within_2_s_with_exit_0(spawn, probe, tmp_path, sig):
    bag = sample_bag(tmp_path / "b", 400)
    imu = probe.subscribe(topics.IMU, Imu, profile_for(topics.IMU), raw=True)
    player = spawn(
        "sideslip-play", str(bag), "--rate", "0.1", "--topics", topics.IMU,
        "--wait-subscribers", "20",
    )  # fmt: skip
    wait_for(lambda: len(imu) >= 2, 20, "playback under way")
    code, seconds = player.stop(sig)
    assert code == 0, player.output()
    assert seconds < 2.0
    assert "played" in player.output()


def test_truncated_bag_plays_its_readable_part_and_says_so(spawn, tmp_path):
    from mcap.reader import make_reader

    bag = sample_bag(tmp_path / "b", 2000)  # about 1.5 MB of messages: two MCAP chunks
    data = (bag / "b.mcap").read_bytes()
    with (bag / "b.mcap").open("rb") as stream:
        chunks = make_reader(stream).get_summary().chunk_indexes
    assert len(chunks) == 2
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: chunks[1].chunk_start_offset + 100])  # inside the second chunk
    readable = len(list(open_bag(cut).messages(topics.SAMPLE_TOPICS)))
    assert 0 < readable < 10_000
    player = spawn("sideslip-play", str(cut), "--rate", "50")
    assert player.proc.wait(30) == 0, player.output()
    out = player.output()
    assert "truncated" in out and "unreadable after" in out
    assert f"played {readable} messages" in out


# --- real DDS: waiting for subscribers (what play_estimator.launch.xml relies on) -------------


def collect(probe, topic: str, msg_type, qos) -> tuple[object, list[bytes]]:
    """A raw subscription of the probe and the list its messages go to."""
    inbox: list[bytes] = []
    sub = probe.node.create_subscription(msg_type, topic, inbox.append, qos, raw=True)
    return sub, inbox


def test_wait_holds_the_first_message_until_a_subscriber_matches(spawn, probe, tmp_path):
    bag = sample_bag(tmp_path / "b", 200)
    expected = raw_messages(bag)[topics.IMU]
    # Ground truth is played but nobody listens to it: only /vehicle/imu is awaited.
    player = spawn(
        "sideslip-play", str(bag), "--reliable", "--wait-subscribers", "20",
        "--wait-topics", topics.IMU,
    )  # fmt: skip
    # The player's publisher exists before anyone subscribes: without the wait it would
    # be publishing now, into nothing (volatile durability keeps no history).
    probe.wait_for_publishers(topics.IMU)
    wait_for(lambda: "waiting up to 20 s" in player.output(), 10, "the player's wait")
    assert player.proc.poll() is None, player.output()
    _sub, imu = collect(probe, topics.IMU, Imu, RELIABLE_DEEP)
    assert player.proc.wait(30) == 0, player.output()
    wait_for(lambda: len(imu) == 200, 5, "all 200 IMU messages")
    assert imu == expected  # from the bag's first message on, in order
    out = player.output()
    assert out.index("waiting up to 20 s for 1 subscriber(s) on each of /vehicle/imu") < out.index(
        "all 1 publisher(s) matched 1 subscriber(s) each; playing"
    )


def test_wait_count_holds_until_that_many_subscribers_match(spawn, probe, tmp_path):
    bag = sample_bag(tmp_path / "b", 200)
    expected = raw_messages(bag)[topics.IMU]
    player = spawn(
        "sideslip-play", str(bag), "--reliable", "--topics", topics.IMU,
        "--wait-subscribers", "20", "--wait-count", "2",
    )  # fmt: skip
    _first, early = collect(probe, topics.IMU, Imu, RELIABLE_DEEP)
    # The player has matched one subscriber (it says so): one too few, so nothing is played.
    wait_for(
        lambda: f"still waiting: {topics.IMU} has 1 subscriber(s), 2 wanted" in player.output(),
        20,
        "the player to match the first subscription",
    )
    assert "publisher(s) matched" not in player.output() and early == []
    _second, inbox = collect(probe, topics.IMU, Imu, RELIABLE_DEEP)
    assert player.proc.wait(30) == 0, player.output()
    wait_for(lambda: len(inbox) == 200, 5, "all 200 messages on the second subscription")
    assert inbox == expected


def test_wait_timeout_plays_anyway_and_names_the_topics_without_subscribers(spawn, tmp_path):
    bag = sample_bag(tmp_path / "b", 40)
    player = spawn(
        "sideslip-play", str(bag), "--topics", topics.IMU, topics.TWIST,
        "--wait-subscribers", "0.5",
    )  # fmt: skip
    assert player.proc.wait(30) == 0, player.output()
    out = player.output()
    assert "gave up waiting after 0.5 s (--wait-subscribers)" in out
    assert f"{topics.IMU} has 0" in out and f"{topics.TWIST} has 0" in out
    assert "playing anyway" in out and "played 80 messages" in out
