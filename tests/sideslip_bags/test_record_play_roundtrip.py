"""A bag played over real DDS and recorded, twice, comes back byte for byte.

original (write_bag) --sideslip-play--> sideslip-record = rec1 --sideslip-play--> rec2

Byte equality: the player publishes each message's stored CDR bytes with
``publish(bytes)`` and the recorder subscribes raw, so no process deserialises or
re-serialises a message and Fast-CDR never gets the chance to pad one (Fast-CDR pads
the messages *it* serialises to 8-byte alignment, e.g. JointState to 92 bytes, where
rosbags writes fewer). What DDS carries is the payload as given, so the recordings equal
the original exactly, padding included or not; this test asserts that strictly.

Order: DDS keeps the order of one writer's messages, but not the order across topics
that are published at the same instant (ros2 bag behaves the same), so the comparison
is per topic.
"""

from __future__ import annotations

import signal
from pathlib import Path

import numpy as np
import yaml
from rosbags.rosbag2 import Reader

from sideslip_msgs_py import topics
from sideslip_msgs_py.bag import read_bag, write_bag
from sideslip_msgs_py.sample import SampleArrays, SensorNoiseSigma

T0_NS = 1_700_000_000 * 10**9
STEP_NS = 2_500_000  # 400 Hz
SAMPLES = 400  # 1 s


def noisy_bag(path: Path, n: int) -> Path:
    """``n`` noisy 400-Hz samples on all five sample topics (a plausible signal, not physics)."""
    rng = np.random.default_rng(42)
    t = np.arange(n) * (STEP_NS * 1e-9)
    v_y = 0.8 * np.sin(2 * np.pi * 0.5 * t)
    r = 0.3 * np.sin(2 * np.pi * 0.5 * t + 0.2)
    arrays = SampleArrays(
        stamp_ns=T0_NS + np.arange(n, dtype=np.int64) * STEP_NS,
        x_v_mps=20.0 + rng.normal(0, 0.28, n),
        y_v_mps=v_y + rng.normal(0, 0.28, n),
        x_a_mps2=rng.normal(0, 0.1, n),
        y_a_mps2=20.0 * r + rng.normal(0, 0.1, n),
        yaw_rate_radps=r + rng.normal(0, 0.0035, n),
        stl_m=0.02 * np.sin(2 * np.pi * 0.5 * t),
        stl_rate_mps=0.02 * np.pi * np.cos(2 * np.pi * 0.5 * t),
        truth_v_x_mps=np.full(n, 20.0),
        truth_v_y_mps=v_y,
        truth_yaw_rate_radps=r,
    )
    return write_bag(path, arrays, sigma=SensorNoiseSigma.paper(), run_metadata={"seed": 42})


def per_topic_bytes(bag: Path) -> dict[str, list[bytes]]:
    with Reader(bag) as reader:
        out: dict[str, list[bytes]] = {c.topic: [] for c in reader.connections}
        for conn, _, data in reader.messages():
            out[conn.topic].append(bytes(data))
    return out


def record_a_playback(spawn, bag: Path, out: Path) -> None:
    """Record ``bag`` played reliably (lossless) into ``out``; both tools exit 0."""
    recorder = spawn("sideslip-record", "--out", str(out), name=f"record-{out.name}")
    # The player starts only when the recorder has subscribed to all of its topics, and
    # exits after the recorder has acknowledged every message.
    player = spawn(
        "sideslip-play", str(bag), "--reliable", "--wait-subscribers", "20", "--rate", "4",
        name=f"play-{bag.name}",
    )  # fmt: skip
    assert player.proc.wait(60) == 0, player.output()
    assert "all 5 publisher(s) matched" in player.output()
    code, seconds = recorder.stop(signal.SIGINT)
    assert code == 0 and seconds < 2.0, recorder.output()


def test_play_record_play_record_gives_the_original_bytes_per_topic(spawn, scratch_dir):
    original = noisy_bag(scratch_dir / "original", SAMPLES)
    rec1, rec2 = scratch_dir / "rec1", scratch_dir / "rec2"
    record_a_playback(spawn, original, rec1)
    record_a_playback(spawn, rec1, rec2)

    want = per_topic_bytes(original)
    assert set(want) == set(topics.SAMPLE_TOPICS)
    assert all(len(v) == SAMPLES for v in want.values())
    first, second = per_topic_bytes(rec1), per_topic_bytes(rec2)
    for topic in topics.SAMPLE_TOPICS:
        assert len(first[topic]) == SAMPLES, topic
        assert first[topic] == want[topic], f"{topic}: first recording differs"
        assert second[topic] == first[topic], f"{topic}: second recording differs"
    assert set(first) == set(second) == set(want)  # nothing else was recorded

    # The recordings decode to the original samples, and say what was offered.
    assert read_bag(rec2).samples == read_bag(original).samples
    info = yaml.safe_load((rec1 / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert (info["version"], info["storage_identifier"], info["message_count"]) == (
        9,
        "mcap",
        5 * SAMPLES,
    )
    for entry in info["topics_with_message_count"]:
        meta = entry["topic_metadata"]
        assert meta["serialization_format"] == "cdr"
        assert [p["reliability"] for p in meta["offered_qos_profiles"]] == ["reliable"]
