"""``sideslip-record``: record contract topics into a rosbag2 MCAP bag, like ``ros2 bag record``.

The recorder watches the ROS graph and subscribes to each requested topic when its
first publisher appears, with a QoS that matches what the publishers offer
(:func:`~.offered_qos.subscription_qos`), and records those offered profiles in the bag.
Subscriptions are raw: each message's CDR bytes go into the bag unchanged, logged at
the time the recorder takes it from DDS (system clock, ns; ``ros2 bag record`` does the
same). Messages are written as they arrive and the bag is finished on SIGINT/SIGTERM
or after ``--max-duration``; at the stop, messages DDS has already received are taken
and stored first.

Crash safety: every ``--flush-period`` the messages received so far go into the .mcap
file and a provisional metadata.yaml is rewritten (:mod:`.bagsink`). A recorder killed
without warning loses at most the messages of its last flush period (plus any DDS had
not yet handed over); ``sideslip-record --reindex DIR`` (:mod:`.reindex`, no rclpy)
then finishes the bag for rosbags and ``ros2 bag``.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any, Final

from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from sideslip_msgs_py.errors import BagError
from sideslip_msgs_py.nodes.qos import to_rclpy
from sideslip_msgs_py.nodes.runtime import StopFlag, run
from sideslip_msgs_py.qos import QosSpec, Reliability

from .bagsink import BagSink, open_sink
from .errors import OptionError, ToolError
from .msgtypes import check_recordable, jazzy_typestore, message_class
from .offered_qos import OfferedQos, all_reliable, describe, subscription_qos
from .options import check_positive, contract_topics, fail, format_counts, split_ros_args
from .reindex import reindex

PROG: Final = "sideslip-record"
NODE_NAME: Final = "sideslip_record"

DISCOVERY_PERIOD_S: Final = 0.1
"""How often the graph is checked for new publishers [s]."""

DEFAULT_FLUSH_PERIOD_S: Final = 1.0
"""How often received messages are written to the .mcap file [s]: what a killed recorder
loses at most (measured: up to 1.00 s, about 2000 messages of the five 400-Hz sample
topics). Each flush ends an MCAP chunk, which zstd compresses less well: at 1 s the bag
is 5 % larger than with full 1-MiB chunks, at 0.5 s 10 %, at 0.1 s 15 %. A second is
short against a drive of minutes and costs little; pass a shorter ``--flush-period``
where that second matters."""

DRAIN_BATCH: Final = 256
"""Messages taken from one subscription per callback (fewer executor round trips)."""

CLOSE_DRAIN_BUDGET_S: Final = 1.0
"""Time allowed at stop for taking messages DDS has already received [s]."""


@dataclass(frozen=True, slots=True)
class RecordOptions:
    """Options of ``sideslip-record`` (see its ``--help``).

    Attributes:
        out: output bag directory.
        topics: (topic, type name) pairs to record.
        force: replace an existing bag at ``out``.
        compress: zstd-compress the MCAP chunks.
        max_duration_s: stop after this long [s] (wall clock from start); None: never.
        flush_period_s: write received messages to the file this often [s].
    """

    out: Path
    topics: tuple[tuple[str, str], ...]
    force: bool = False
    compress: bool = True
    max_duration_s: float | None = None
    flush_period_s: float = DEFAULT_FLUSH_PERIOD_S


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=(
            "Record sideslip contract topics into a rosbag2 directory (metadata.yaml + "
            "zstd-compressed .mcap, metadata version 9), like `ros2 bag record -s mcap`. "
            "Each topic is subscribed when its first publisher appears, reliable only if "
            "every publisher offers reliable, and the offered QoS is stored in the bag. "
            "Messages are stored byte for byte as received, logged at their receive time "
            "(system clock). Stop with Ctrl-C (SIGINT) or SIGTERM: the bag is closed "
            "cleanly and the number of messages per topic is logged. Every --flush-period "
            "the received messages are written to the .mcap file and a provisional "
            "metadata.yaml is updated, so a recorder killed without warning (SIGKILL, a "
            "crash) loses at most its last flush period; `sideslip-record --reindex DIR` "
            "then finishes such a bag (summary, final metadata.yaml) for rosbags and "
            "`ros2 bag`. Our own readers (sideslip-play, training) read it even before."
        ),
        epilog=(
            "ROS arguments go after --ros-args, e.g. `--ros-args -r __node:=rec1` or "
            "`-r /vehicle/imu:=/car/imu` (the bag then holds the remapped name). "
            "Exit status: 0 after a clean stop or a reindex, 2 for refused input "
            "(existing --out without --force, a topic outside the contract, a --reindex "
            "DIR that is not an MCAP bag directory or already has final metadata). "
            "Example: sideslip-record --out runs/drive1 --topics /vehicle/imu /sideslip"
        ),
    )
    target = parser.add_mutually_exclusive_group(required=True)
    target.add_argument("--out", type=Path, help="output bag directory")
    target.add_argument(
        "--reindex",
        type=Path,
        metavar="DIR",
        help=(
            "do not record: finish the bag directory DIR whose recorder was killed. Its "
            ".mcap files are read up to their first damaged record; a file that rosbags "
            "cannot read is rewritten with the readable messages (the original is kept as "
            "*.mcap.damaged), and metadata.yaml is written with every topic, its type, "
            "offered QoS and message count. Refused when DIR already has the metadata of "
            "a finished bag or its recorder still runs, unless --force"
        ),
    )
    parser.add_argument(
        "--topics",
        nargs="+",
        metavar="T",
        help="contract topics to record (default: every contract topic)",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help=(
            "replace an existing bag at --out (bags only); with --reindex, rewrite an "
            "existing final metadata.yaml"
        ),
    )
    parser.add_argument("--no-compress", action="store_true", help="write uncompressed MCAP chunks")
    parser.add_argument(
        "--max-duration",
        type=float,
        metavar="S",
        help="stop by itself after S seconds of wall time (default: until signalled)",
    )
    parser.add_argument(
        "--flush-period",
        type=float,
        metavar="S",
        help=(
            "write received messages to the .mcap file every S seconds (default "
            f"{DEFAULT_FLUSH_PERIOD_S:g}): a recorder killed without warning loses at most "
            "the last S seconds. Shorter periods cost file size (each flush ends a "
            "compressed chunk: +5 %% at 1 s, +10 %% at 0.5 s, +15 %% at 0.1 s)"
        ),
    )
    return parser


_RECORDING_ONLY: Final = (
    ("topics", "--topics"),
    ("max_duration", "--max-duration"),
    ("flush_period", "--flush-period"),
    ("no_compress", "--no-compress"),
)


def parse_options(args: argparse.Namespace) -> RecordOptions:
    """Validated recording options; raises :class:`~.errors.OptionError` naming the bad one."""
    max_duration = args.max_duration
    if max_duration is not None:
        check_positive(max_duration, "--max-duration")
    flush_period = args.flush_period
    if flush_period is None:
        flush_period = DEFAULT_FLUSH_PERIOD_S
    check_positive(flush_period, "--flush-period")
    chosen = contract_topics(args.topics)
    return RecordOptions(
        out=args.out,
        topics=tuple(chosen.items()),
        force=args.force,
        compress=not args.no_compress,
        max_duration_s=max_duration,
        flush_period_s=flush_period,
    )


def check_reindex_options(args: argparse.Namespace) -> None:
    """Raise :class:`~.errors.OptionError` for a recording option given with --reindex."""
    for attr, option in _RECORDING_ONLY:
        if getattr(args, attr) not in (None, False):
            msg = f"{option} is a recording option; --reindex DIR takes only --force"
            raise OptionError(msg)


class Recorder(Node):
    """Subscribes raw to the requested topics as publishers appear; writes into a sink."""

    def __init__(self, options: RecordOptions, sink: BagSink, flag: StopFlag) -> None:
        super().__init__(NODE_NAME)
        self._sink = sink
        self._flag = flag
        self._wanted = {self.resolve_topic_name(t): msgtype for t, msgtype in options.topics}
        self._subs: dict[str, Any] = {}
        self._specs: dict[str, QosSpec] = {}
        self._warned: set[tuple[str, str]] = set()
        self._discover()
        # Steady clock: with use_sim_time, ROS-time timers would stop with /clock.
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(DISCOVERY_PERIOD_S, self._discover, clock=steady)
        self.create_timer(options.flush_period_s, sink.flush, clock=steady)
        if options.max_duration_s is not None:
            self._stop_timer = self.create_timer(
                options.max_duration_s, self._on_max_duration, clock=steady
            )
        self.get_logger().info(
            f"recording to {sink.path} (flushed every {options.flush_period_s:g} s): "
            f"waiting for publishers on {len(self._wanted)} topic(s)"
        )

    # --- discovery ------------------------------------------------------------------------

    def _discover(self) -> None:
        for topic, msgtype in self._wanted.items():
            infos = self.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            offers = []
            for info in infos:
                if info.topic_type == msgtype:
                    offers.append(OfferedQos.from_rclpy(info.qos_profile))
                else:
                    self._warn_once(
                        (topic, info.topic_type),
                        f"{topic}: a publisher has type {info.topic_type}, expected {msgtype}; "
                        "not recording it",
                    )
            if not offers:
                continue
            spec = self._specs.get(topic)
            if spec is None:
                self._subscribe(topic, msgtype, offers)
            elif spec.reliability == Reliability.RELIABLE and not all_reliable(offers):
                self._warn_once(
                    (topic, "qos"),
                    f"{topic}: a publisher that appeared later offers best effort; the "
                    "reliable subscription does not receive from it",
                )

    def _subscribe(self, topic: str, msgtype: str, offers: Sequence[OfferedQos]) -> None:
        spec = subscription_qos(offers)
        self._sink.add_topic(topic, msgtype, offers)
        self._subs[topic] = self.create_subscription(
            message_class(msgtype),
            topic,
            partial(self._on_message, topic),
            to_rclpy(spec),
            raw=True,
        )
        self._specs[topic] = spec
        self.get_logger().info(
            f"recording {topic} ({msgtype}, {describe(spec)}, {len(offers)} publisher(s))"
        )

    def _warn_once(self, key: tuple[str, str], text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.get_logger().warning(text)

    # --- messages ---------------------------------------------------------------------------

    def _on_message(self, topic: str, data: bytes) -> None:
        # One message per callback, stamped as it is taken: taking a topic's backlog in
        # a batch would stamp a burst of one topic before the other topics' messages of
        # the same instants, and a replay would then deliver them out of step.
        self._sink.write(topic, time.time_ns(), data)

    def _drain(self, topic: str, limit: int) -> bool:
        """Store up to ``limit`` more waiting messages of ``topic``; True if more may wait.

        Taking them here saves one executor round trip per message when the recorder
        has fallen behind. The log time is the take time, as for the callback's message
        (DDS's reception stamp is not given to callbacks by every executor, and mixing
        the two could reorder a topic's log times).
        """
        sub = self._subs[topic]
        for _ in range(limit):
            with sub.handle:
                taken = sub.handle.take_message(sub.msg_type, sub.raw)
            if taken is None:
                return False
            self._sink.write(topic, time.time_ns(), taken[0])
        return True

    def _on_max_duration(self) -> None:
        self._stop_timer.cancel()
        self.get_logger().info("--max-duration reached")
        self._flag.set("max-duration")

    # --- shutdown ---------------------------------------------------------------------------

    def close(self) -> None:
        """Store what DDS already received (bounded time), then finish the bag."""
        try:
            deadline = time.monotonic() + CLOSE_DRAIN_BUDGET_S
            for topic in self._subs:
                while time.monotonic() < deadline and self._drain(topic, DRAIN_BATCH):
                    pass
        except Exception as err:  # the bag must still be closed
            self.get_logger().error(f"could not take the last messages: {err}")
        finally:
            self._sink.close()
        counts = self._sink.counts
        self.get_logger().info(
            f"recorded {sum(counts.values())} messages to {self._sink.path}: "
            f"{format_counts(counts)}"
        )


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``sideslip-record``; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    ours, _ = split_ros_args(argv)
    args = build_parser().parse_args(ours)
    if args.reindex is not None:
        return reindex_main(args)
    try:
        options = parse_options(args)
        typestore = jazzy_typestore()
        for _, msgtype in options.topics:
            message_class(msgtype)
            check_recordable(msgtype, typestore)
        sink = open_sink(options.out, compress=options.compress, force=options.force)
    except (ToolError, BagError) as err:
        return fail(PROG, err)
    try:
        return run(lambda flag: Recorder(options, sink, flag), [PROG, *argv])
    finally:
        sink.close()  # no-op after the node's close(); covers a failure before it


def reindex_main(args: argparse.Namespace) -> int:
    """``sideslip-record --reindex DIR``: finish a killed recording; returns the exit status."""
    try:
        check_reindex_options(args)
        result = reindex(args.reindex, force=args.force)
    except (ToolError, BagError) as err:
        return fail(PROG, err)
    for note in result.notes:
        print(f"{PROG}: warning: {note}", file=sys.stderr)
    span_s = (result.end_ns - result.start_ns) * 1e-9
    print(
        f"{PROG}: reindexed {result.path}: {result.message_count} messages over "
        f"{span_s:.3f} s in {', '.join(result.files)} ({format_counts(result.topic_counts)}); "
        "metadata.yaml written"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
