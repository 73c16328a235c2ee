"""``sideslip-play``: publish a bag's messages again, like ``ros2 bag play``.

Each message's recorded CDR bytes are published unchanged, at its log time relative to
the first message scaled by ``--rate``, on an absolute schedule
(:class:`~sideslip_msgs_py.schedule.Schedule`, waiting with
:func:`~sideslip_msgs_py.schedule.wait_until`): publishing runs on its own thread and
never accumulates drift. The executor thread only serves ``/clock`` (``--clock``). With
``--wait-subscribers`` the first message waits until the awaited topics have their
subscribers (bounded; then it plays anyway, with a warning). At the end of the bag the
player waits (briefly) until reliable subscribers have acknowledged everything, then
exits 0.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from collections.abc import Sequence
from contextlib import closing
from pathlib import Path
from typing import Any, Final

from rclpy.duration import Duration
from rclpy.node import Node

from sideslip_msgs_py import topics as contract
from sideslip_msgs_py.errors import BagError
from sideslip_msgs_py.nodes.qos import profile_for, to_rclpy
from sideslip_msgs_py.nodes.runtime import StopFlag, run
from sideslip_msgs_py.schedule import Schedule, wait_until

from .bagsource import BagSource, open_bag
from .errors import ToolError
from .msgtypes import message_class
from .offered_qos import describe
from .options import (
    check_non_negative,
    check_positive,
    fail,
    format_counts,
    parse_remaps,
    split_ros_args,
)
from .playplan import DEFAULT_CLOCK_HZ, PlayOptions, PlayPlan, plan_playback

PROG: Final = "sideslip-play"
NODE_NAME: Final = "sideslip_play"

EXIT_PLAY_FAILED: Final = 1
"""Exit status when publishing failed part way (the error is logged)."""

MATCH_POLL_S: Final = 0.02
"""Poll period while waiting for subscribers [s]."""

ACK_TIMEOUT_S: Final = 5.0
"""Longest wait at the end for reliable subscribers to acknowledge everything [s]."""

JOIN_TIMEOUT_S: Final = 1.5
"""Longest wait for the publishing thread after a stop [s]."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=(
            "Publish the messages of a bag (rosbag2 directory or bare .mcap) on their "
            "topics, byte for byte as recorded, with the recorded timing. Each topic is "
            "published with the QoS its recorder saw offered (else the contract QoS). "
            "A truncated bag plays its readable part, with a warning. Exits 0 at the end "
            "of the bag or on Ctrl-C (SIGINT) / SIGTERM."
        ),
        epilog=(
            "Put BAG before options that take several values (--topics, --remap). ROS "
            "arguments go after --ros-args. Exit status: 0 at the end or when stopped, "
            "2 for refused input (missing or unreadable bag, unknown message type, bad "
            "--remap, non-positive --rate, a --wait-topics topic that is not played), 1 if "
            "publishing failed part way. "
            "Example: sideslip-play runs/drive1 --rate 2 --clock --topics /vehicle/imu "
            "--remap /vehicle/imu:=/car/imu"
        ),
    )
    parser.add_argument("bag", type=Path, metavar="BAG", help="rosbag2 directory or .mcap file")
    parser.add_argument(
        "--rate",
        type=float,
        default=1.0,
        metavar="R",
        help="speed factor: 2 plays twice as fast as recorded (default 1)",
    )
    parser.add_argument(
        "--clock",
        type=float,
        nargs="?",
        const=DEFAULT_CLOCK_HZ,
        metavar="HZ",
        help=(
            f"publish {contract.CLOCK} (rosgraph_msgs/Clock) with bag time, HZ times per "
            f"second of wall time (default {DEFAULT_CLOCK_HZ:g}); the bag's own "
            f"{contract.CLOCK} is then not played"
        ),
    )
    parser.add_argument("--loop", action="store_true", help="start again at the end, until stopped")
    parser.add_argument(
        "--topics", nargs="+", metavar="T", help="bag topics to play (default: all)"
    )
    parser.add_argument(
        "--remap",
        nargs="+",
        action="extend",
        default=[],
        metavar="OLD:=NEW",
        help="publish bag topic OLD on NEW (repeatable)",
    )
    parser.add_argument(
        "--wait-subscribers",
        type=float,
        default=0.0,
        metavar="S",
        help=(
            "before the first message, wait up to S seconds until every awaited topic "
            "(--wait-topics, default all played) has matched --wait-count subscriptions; "
            "after S seconds play anyway, with a warning naming the topics that lack them"
        ),
    )
    parser.add_argument(
        "--wait-topics",
        nargs="+",
        metavar="T",
        help=(
            "the topics to wait for, as published (after --remap), e.g. only those an "
            "estimator subscribes to (default: every played topic)"
        ),
    )
    parser.add_argument(
        "--wait-count",
        type=int,
        default=1,
        metavar="N",
        help="subscriptions each awaited topic must have matched (default 1)",
    )
    parser.add_argument(
        "--reliable",
        action="store_true",
        help=(
            "publish every topic reliable with a deep keep-last history, so that a "
            "reliable subscriber that keeps up loses nothing"
        ),
    )
    parser.add_argument(
        "--delay", type=float, default=0.0, metavar="S", help="wait S seconds before playing"
    )
    return parser


def parse_options(args: argparse.Namespace) -> PlayOptions:
    """Validated options; raises :class:`~.errors.OptionError` naming the bad one."""
    if args.clock is not None:
        check_positive(args.clock, "--clock")
    return PlayOptions(
        bag=args.bag,
        rate=check_positive(args.rate, "--rate"),
        clock_hz=args.clock,
        loop=args.loop,
        topics=tuple(dict.fromkeys(args.topics or ())),
        remaps=tuple(parse_remaps(args.remap).items()),
        wait_subscribers_s=check_non_negative(args.wait_subscribers, "--wait-subscribers"),
        wait_topics=tuple(args.wait_topics or ()),
        wait_count=args.wait_count,
        reliable=args.reliable,
        delay_s=check_non_negative(args.delay, "--delay"),
    )


class Player(Node):
    """Publishes a planned bag on a worker thread; sets the stop flag when done."""

    def __init__(
        self, source: BagSource, plan: PlayPlan, options: PlayOptions, flag: StopFlag
    ) -> None:
        super().__init__(NODE_NAME)
        self._source = source
        self._options = options
        self._flag = flag
        self._pubs: dict[str, Any] = {}
        self._awaited: list[Any] = []
        for topic in plan.topics:
            try:
                self._pubs[topic.bag_topic] = self.create_publisher(
                    message_class(topic.msgtype), topic.out_topic, to_rclpy(topic.qos)
                )
            except Exception as err:  # e.g. an invalid name given with --remap
                msg = f"{PROG}: error: cannot publish on {topic.out_topic}: {err}"
                raise SystemExit(msg) from None
            if topic.out_topic in plan.wait_topics:
                self._awaited.append(self._pubs[topic.bag_topic])
            renamed = f" as {topic.out_topic}" if topic.out_topic != topic.bag_topic else ""
            self.get_logger().info(
                f"{topic.bag_topic}{renamed}: {topic.count} messages, {topic.msgtype}, "
                f"{describe(topic.qos)}"
            )
        self.counts = dict.fromkeys(self._pubs, 0)
        self.passes = 0
        self.failed: str | None = None
        self._schedule: Schedule | None = None
        self._clock_pub = None
        if options.clock_hz is not None:
            from rosgraph_msgs.msg import Clock

            self._clock_msg = Clock()
            self._clock_pub = self.create_publisher(
                Clock, contract.CLOCK, profile_for(contract.CLOCK)
            )
            self.create_timer(1.0 / options.clock_hz, self._publish_clock)
        self._worker = threading.Thread(target=self._play_safely, name="play", daemon=True)
        self._worker.start()

    # --- publishing thread ------------------------------------------------------------------

    def _play_safely(self) -> None:
        try:
            self._play()
        except BagError as err:  # damage that rosbags found part way through
            self.get_logger().warning(f"bag truncated: {err}; played the part before it")
        except Exception as err:
            self.failed = f"{type(err).__name__}: {err}"
            self.get_logger().error(f"playback failed: {self.failed}")
        finally:
            self._schedule = None
            self._flag.set("end of bag")

    def _play(self) -> None:
        options = self._options
        if options.wait_subscribers_s > 0 and not self._wait_for_subscribers():
            return
        if options.delay_s > 0 and self._flag.wait(options.delay_s):
            return
        while not self._flag.is_set():
            self.passes += 1
            started = time.monotonic()
            played = self._play_once()
            self.get_logger().debug(
                f"pass {self.passes}: {played} messages in {time.monotonic() - started:.3f} s"
            )
            if not (options.loop and played):
                break
        self._schedule = None  # /clock stops at the end of the bag
        if not self._flag.is_set():
            self._wait_for_acks()

    def _play_once(self) -> int:
        """One pass through the bag; returns the number of messages published."""
        schedule = None
        published = 0
        pubs, counts, flag = self._pubs, self.counts, self._flag
        with closing(self._source.messages(pubs)) as messages:  # closes the bag on a stop
            for topic, log_time_ns, data in messages:
                if schedule is None:
                    schedule = Schedule(time.monotonic_ns(), log_time_ns, self._options.rate)
                    self._schedule = schedule
                if not wait_until(schedule.deadline_ns(log_time_ns), flag):
                    break
                pubs[topic].publish(data)
                counts[topic] += 1
                published += 1
        return published

    def _wait_for_subscribers(self) -> bool:
        """Wait until every awaited publisher has matched ``wait_count`` subscriptions
        or the timeout passed (then warn and play anyway); False when stopped meanwhile."""
        limit_s, n = self._options.wait_subscribers_s, self._options.wait_count
        names = ", ".join(p.topic_name for p in self._awaited)
        self.get_logger().info(
            f"waiting up to {limit_s:g} s for {n} subscriber(s) on each of {names}"
        )
        deadline = time.monotonic() + limit_s
        seen: dict[str, int] = dict.fromkeys((p.topic_name for p in self._awaited), 0)
        while True:
            counts = {p.topic_name: p.get_subscription_count() for p in self._awaited}
            missing = {topic: c for topic, c in counts.items() if c < n}
            if not missing:
                self.get_logger().info(
                    f"all {len(counts)} publisher(s) matched {n} subscriber(s) each; playing"
                )
                return True
            lacking = ", ".join(f"{topic} has {c}" for topic, c in missing.items())
            if counts != seen:  # progress, so that a long wait shows what it waits for
                seen = counts
                self.get_logger().info(f"still waiting: {lacking} subscriber(s), {n} wanted")
            if time.monotonic() > deadline:
                self.get_logger().warning(
                    f"gave up waiting after {limit_s:g} s (--wait-subscribers): {lacking} "
                    f"subscriber(s), {n} wanted; playing anyway"
                )
                return True
            if self._flag.wait(MATCH_POLL_S):
                return False

    def _wait_for_acks(self) -> None:
        started = time.monotonic()
        deadline = started + ACK_TIMEOUT_S
        for pub in self._pubs.values():
            while not pub.wait_for_all_acked(Duration(nanoseconds=50_000_000)):
                if self._flag.is_set() or time.monotonic() > deadline:
                    self.get_logger().warning(
                        f"{pub.topic_name}: not every message was acknowledged by the "
                        "reliable subscribers"
                    )
                    return
        self.get_logger().debug(f"acknowledged after {time.monotonic() - started:.3f} s")

    # --- executor thread --------------------------------------------------------------------

    def _publish_clock(self) -> None:
        schedule = self._schedule
        if schedule is None or self._clock_pub is None:
            return
        now_ns = min(schedule.bag_time_ns(time.monotonic_ns()), self._source.end_ns)
        stamp = self._clock_msg.clock
        stamp.sec, stamp.nanosec = divmod(now_ns, 1_000_000_000)
        self._clock_pub.publish(self._clock_msg)

    def close(self) -> bool:
        """Stop the publishing thread and log what was played; False if the thread is
        still running after the timeout (the node must then not be destroyed under it)."""
        self._flag.set()
        self._worker.join(JOIN_TIMEOUT_S)
        self.get_logger().info(
            f"played {sum(self.counts.values())} messages in {self.passes} pass(es): "
            f"{format_counts(self.counts)}"
        )
        return not self._worker.is_alive()


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``sideslip-play``; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    ours, _ = split_ros_args(argv)
    args = build_parser().parse_args(ours)
    try:
        options = parse_options(args)
        source = open_bag(options.bag)
        plan = plan_playback(source, options)
    except (ToolError, BagError) as err:
        return fail(PROG, err)
    if source.truncated:
        print(
            f"{PROG}: warning: {source.path} is truncated; playing its readable part",
            file=sys.stderr,
        )
    for note in (*source.notes, *plan.notes):
        print(f"{PROG}: note: {note}", file=sys.stderr)

    players: list[Player] = []

    def make_player(flag: StopFlag) -> Player:
        players.append(Player(source, plan, options, flag))
        return players[-1]

    code = run(make_player, [PROG, *argv])
    if code == 0 and players and players[0].failed:
        return EXIT_PLAY_FAILED
    return code


if __name__ == "__main__":
    sys.exit(main())
