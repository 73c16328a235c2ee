"""Crash-safe recording: a killed recorder's bag, ``sideslip-record --reindex``, refusals;
then real recorders killed with SIGKILL mid-stream."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from ros_support import BIN, wait_for
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from std_msgs.msg import Float64

from sideslip_bags import record
from sideslip_bags.bagmeta import IN_PROGRESS_KEY
from sideslip_bags.reindex import reindex
from sideslip_msgs_py import topics
from sideslip_msgs_py.bag import open_raw_bag, read_bag
from sideslip_msgs_py.nodes.qos import profile_for
from sideslip_training.dataset import load_runs

from .test_record import sample_bag


def metadata(bag: Path) -> dict:
    return yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


def any_reader_messages(bag: Path) -> list[tuple[str, int, bytes]]:
    """Every message as rosbags' AnyReader gives it, each deserialised once (type check)."""
    with AnyReader([bag]) as reader:
        out = []
        for conn, t, data in reader.messages():
            reader.deserialize(data, conn.msgtype)
            out.append((conn.topic, t, bytes(data)))
    return out


KILLED_SINK = """
import os, signal, sys
from pathlib import Path
from rosbags.rosbag2 import Reader
from sideslip_bags.bagsink import open_sink
from sideslip_bags.offered_qos import OfferedQos

source, out, flushed, written = Path(sys.argv[1]), Path(sys.argv[2]), *map(int, sys.argv[3:])
sink = open_sink(out)
with Reader(source) as reader:
    for conn in reader.connections:
        offers = [OfferedQos.from_rosbags(q) for q in conn.ext.offered_qos_profiles]
        sink.add_topic(conn.topic, conn.msgtype, offers)
    for i, (conn, t, data) in enumerate(reader.messages()):
        if i == written:
            break
        if i == flushed:
            sink.flush()
        sink.write(conn.topic, t, data)
os.kill(os.getpid(), signal.SIGKILL)
"""


def killed_sink(source: Path, out: Path, *, flushed: int, written: int) -> list[tuple]:
    """A recorder's sink in another process, fed ``written`` messages of ``source``,
    flushed after the first ``flushed``, then SIGKILLed. Returns the flushed messages."""
    args = [str(source), str(out), str(flushed), str(written)]
    done = subprocess.run([sys.executable, "-c", KILLED_SINK, *args], timeout=60, check=False)
    assert done.returncode == -signal.SIGKILL
    with Reader(source) as reader:
        return [(c.topic, t, bytes(d)) for c, t, d in reader.messages()][:flushed]


# --- a killed sink, reindexed ------------------------------------------------------------------


def test_killed_recording_has_provisional_metadata_and_reindex_makes_rosbags_read_it(
    tmp_path: Path,
) -> None:
    source = sample_bag(tmp_path / "src", 1000)
    out = tmp_path / "rec"
    flushed = killed_sink(source, out, flushed=3001, written=4500)
    original = (out / "rec.mcap").read_bytes()

    # Before: our readers take it (record by record); rosbags refuses the .mcap.
    provisional = metadata(out)
    assert IN_PROGRESS_KEY in provisional["custom_data"]
    assert provisional["message_count"] == 3001
    assert open_raw_bag(out).truncated
    assert sum(1 for _ in open_raw_bag(out).messages()) == 3001
    with pytest.raises(Exception, match="magic"):
        Reader(out).open()

    result = reindex(out)

    assert any_reader_messages(out) == flushed  # every flushed message, bytes and log times
    assert result.message_count == 3001 and result.kept_damaged == (out / "rec.mcap.damaged",)
    assert (out / "rec.mcap.damaged").read_bytes() == original  # recorded data is kept
    assert "without summary and footer" in result.notes[0]
    info = metadata(out)
    assert (info["version"], info["storage_identifier"]) == (9, "mcap")
    assert info["relative_file_paths"] == ["rec.mcap"] and info["custom_data"] is None
    assert info["message_count"] == 3001
    assert info["starting_time"]["nanoseconds_since_epoch"] == flushed[0][1]
    assert info["duration"]["nanoseconds"] == flushed[-1][1] - flushed[0][1]
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    with Reader(source) as reader:
        expected_offers = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
    for entry in info["topics_with_message_count"]:
        meta = entry["topic_metadata"]
        assert entry["message_count"] == sum(1 for m in flushed if m[0] == meta["name"])
        assert meta["serialization_format"] == "cdr"
        assert meta["type_description_hash"] == jazzy.hash_rihs01(meta["type"])
        assert meta["offered_qos_profiles"][0]["reliability"] == "best_effort"
    with Reader(out) as reader:  # offered QoS as the recorder wrote them
        assert {c.topic: c.ext.offered_qos_profiles for c in reader.connections} == expected_offers
    contents = read_bag(out)
    assert not contents.truncated and len(contents.samples) == 600


def test_a_file_cut_inside_a_chunk_keeps_its_whole_chunks(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    bag = sample_bag(tmp_path / "b", 2000)  # two MCAP chunks
    with (bag / "b.mcap").open("rb") as stream:
        chunks = make_reader(stream).get_summary().chunk_indexes
    data = (bag / "b.mcap").read_bytes()
    cut = tmp_path / "cut"
    cut.mkdir()  # a killed old recorder's bag: no metadata.yaml at all
    (cut / "cut.mcap").write_bytes(data[: chunks[1].chunk_start_offset + 100])
    readable = sum(1 for _ in open_raw_bag(cut / "cut.mcap").messages())
    assert 0 < readable < 10_000
    # Our tools open the directory as it is, and say how to make it whole.
    raw = open_raw_bag(cut)
    assert raw.truncated and sum(1 for _ in raw.messages()) == readable
    assert "--reindex" in raw.notes[0]

    result = reindex(cut)

    assert result.message_count == readable
    assert len(any_reader_messages(cut)) == readable
    assert (cut / "cut.mcap.damaged").stat().st_size == chunks[1].chunk_start_offset + 100
    with Reader(cut) as reader:
        assert reader.message_count == readable
    assert read_bag(cut).run_metadata == {}  # the run metadata record was in the lost end


def test_an_intact_bag_without_metadata_keeps_its_file_and_gets_its_custom_data_back(
    tmp_path: Path,
) -> None:
    bag = sample_bag(tmp_path / "b", 100)
    before = metadata(bag)
    mcap = (bag / "b.mcap").read_bytes()
    (bag / "metadata.yaml").unlink()

    result = reindex(bag)

    assert result.kept_damaged == () and (bag / "b.mcap").read_bytes() == mcap
    after = metadata(bag)
    assert after["custom_data"] == before["custom_data"]  # from the .mcap's metadata record
    for key in ("message_count", "duration", "starting_time", "relative_file_paths"):
        assert after[key] == before[key]
    assert [t["message_count"] for t in after["topics_with_message_count"]] == [
        t["message_count"] for t in before["topics_with_message_count"]
    ]
    assert read_bag(bag).run_metadata == {"seed": 0}
    assert reindex(bag, force=True).message_count == 500


# --- refusals ------------------------------------------------------------------------------------


def reindex_cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    code = record.main(["--reindex", *args])
    return code, capsys.readouterr().err


def test_reindex_refuses_what_is_not_an_mcap_bag_in_one_line_with_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    fake = tmp_path / "fake"
    fake.mkdir()
    (fake / "fake.mcap").write_bytes(b"not an mcap file")
    cases = [
        (tmp_path / "missing", "no such bag directory"),
        (empty, "holds no .mcap file"),
        (fake, "not an MCAP file"),
        (sample_bag(tmp_path / "b", 4) / "b.mcap", "not a directory"),
    ]
    for path, why in cases:
        code, err = reindex_cli(capsys, str(path))
        assert code == 2, path
        assert err.count("\n") == 1 and err.startswith("sideslip-record: error:") and why in err
    assert list(empty.iterdir()) == [] and [p.name for p in fake.iterdir()] == ["fake.mcap"]


def test_reindex_refuses_a_finished_bag_without_force_and_recording_options(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = sample_bag(tmp_path / "b", 4)
    meta = (bag / "metadata.yaml").read_bytes()
    code, err = reindex_cli(capsys, str(bag))
    assert code == 2 and err.count("\n") == 1 and "finished bag" in err and "--force" in err
    assert (bag / "metadata.yaml").read_bytes() == meta
    code, err = reindex_cli(capsys, str(bag), "--flush-period", "0.5")
    assert code == 2 and err.count("\n") == 1 and "--flush-period is a recording option" in err
    assert record.main(["--reindex", str(bag), "--force"]) == 0
    assert "reindexed" in capsys.readouterr().out


def test_flush_period_must_be_positive(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert record.main(["--out", str(tmp_path / "rec"), "--flush-period", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--flush-period" in err
    assert not (tmp_path / "rec").exists()


# --- real DDS: SIGKILL mid-stream -----------------------------------------------------------------


RATE_HZ = 200.0
FLUSH_PERIOD_S = 0.5
KILL_PHASE = 0.8
"""The kill comes this fraction of a flush period after a flush is seen: late in the
period, with 0.1 s left for the test seeing the flush late (mtime polling, a loaded
machine); seen later than that, the next flush would come before the kill."""
SLACK_S = 0.15
"""Beyond one flush period: timer and scheduling delays on a loaded 2-core machine."""


def test_sigkilled_recorder_loses_at_most_one_flush_period(spawn, probe, scratch_dir, capsys):
    out = scratch_dir / "rec"
    recorder = spawn(
        "sideslip-record", "--out", str(out), "--topics", topics.SIDESLIP,
        "--flush-period", str(FLUSH_PERIOD_S),
    )  # fmt: skip
    pub = probe.publisher(topics.SIDESLIP, Float64, profile_for(topics.SIDESLIP))
    probe.wait_for_subscribers(pub)  # the recorder subscribes when it sees the publisher
    # While it runs, the bag is refused: its recorder is alive.
    code, err = reindex_cli(capsys, str(out))
    assert code == 2 and "still being recorded" in err

    def mtime() -> int:
        return (out / "metadata.yaml").stat().st_mtime_ns  # rewritten at each flush

    # Publish for a second, then kill just before the flush after the next one.
    published_ns: list[int] = []
    start = time.monotonic()
    flushes: list[float] = []
    seen = mtime()
    while not flushes or time.monotonic() < flushes[-1] + KILL_PHASE * FLUSH_PERIOD_S:
        published_ns.append(time.time_ns())
        pub.publish(Float64(data=float(len(published_ns) - 1)))
        time.sleep(max(0.0, start + len(published_ns) / RATE_HZ - time.monotonic()))  # pacing
        if time.monotonic() - start > 1.0 and (now := mtime()) != seen:
            seen = now
            flushes.append(time.monotonic())
        assert time.monotonic() - start < 10, "no flush seen"
    recorder.proc.send_signal(signal.SIGKILL)
    kill_ns = time.time_ns()
    assert recorder.proc.wait(10) == -signal.SIGKILL

    # Our player opens the killed bag as it is (provisional metadata, truncated .mcap).
    killed = open_raw_bag(out)
    assert killed.truncated
    player = spawn("sideslip-play", str(out), "--rate", "20")
    assert player.proc.wait(30) == 0, player.output()
    assert "truncated" in player.output()
    assert f"played {killed.topics[topics.SIDESLIP].count} messages" in player.output()

    done = subprocess.run(
        [str(BIN / "sideslip-record"), "--reindex", str(out)],
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("\n") == 1 and "reindexed" in done.stdout
    assert "original kept as rec.mcap.damaged" in done.stderr

    with AnyReader([out]) as reader:
        rows = [
            (reader.deserialize(data, conn.msgtype).data, t) for conn, t, data in reader.messages()
        ]
    seqs = [int(seq) for seq, _ in rows]
    assert seqs == list(range(len(seqs))), "a reliable topic: a gapless prefix"
    lost = len(published_ns) - len(seqs)
    print(
        f"published {len(published_ns)}, recovered {len(seqs)}, lost {lost} "
        f"({lost / RATE_HZ:.3f} s at {RATE_HZ:g} Hz); last log time "
        f"{(kill_ns - rows[-1][1]) * 1e-9:.3f} s before the kill"
    )
    assert lost >= 0.5 * KILL_PHASE * FLUSH_PERIOD_S * RATE_HZ, "the test kills late in a period"
    assert lost <= RATE_HZ * (FLUSH_PERIOD_S + SLACK_S)
    early = sum(1 for t in published_ns if t < kill_ns - (FLUSH_PERIOD_S + SLACK_S) * 1e9)
    assert len(seqs) >= early, "everything published a flush period before the kill is kept"


def test_sigkilled_recording_of_contract_topics_trains_before_and_after_reindex(spawn, scratch_dir):
    bag = sample_bag(scratch_dir / "src", 4000)  # 10 s: still playing at the kill
    out = scratch_dir / "rec"
    recorder = spawn("sideslip-record", "--out", str(out))  # default flush period
    spawn("sideslip-play", str(bag))

    def flushed_imu() -> int:  # from the provisional metadata.yaml, rewritten at each flush
        if not (out / "metadata.yaml").exists():
            return 0
        entries = metadata(out)["topics_with_message_count"]
        counts = {e["topic_metadata"]["name"]: e["message_count"] for e in entries}
        return counts.get(topics.IMU, 0)

    wait_for(lambda: flushed_imu() >= 400, 20, "a flushed second of /vehicle/imu")
    os.kill(recorder.proc.pid, signal.SIGKILL)
    assert recorder.proc.wait(10) == -signal.SIGKILL

    runs, report = load_runs([out])  # the training loader reads the killed bag as it is
    before = sum(len(run.samples) for run in runs)
    assert before >= 390 and report.truncated == ("rec",)

    assert record.main(["--reindex", str(out)]) == 0
    messages = any_reader_messages(out)
    assert {m[0] for m in messages} == set(topics.SAMPLE_TOPICS)
    contents = read_bag(out)
    assert not contents.truncated and len(contents.samples) >= before
    runs, report = load_runs([out])
    assert sum(len(run.samples) for run in runs) == len(contents.samples)
    assert report.truncated == ()
