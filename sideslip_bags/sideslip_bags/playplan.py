"""What ``sideslip-play`` will do, decided before any DDS entity exists (no rclpy).

:func:`plan_playback` checks the options against the bag (topics and remaps that name
bag topics, message types that have a Python class) and picks each publisher's QoS:
the bag's recorded offers (:func:`~.offered_qos.publisher_qos`), else the contract QoS of a
contract topic, else reliable keep-last 10; ``--reliable`` then makes every topic
reliable with a deep history.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from sideslip_msgs_py import qos as contract_qos
from sideslip_msgs_py import topics as contract
from sideslip_msgs_py.qos import QosSpec

from .bagsource import BagSource
from .errors import OptionError
from .msgtypes import message_class
from .offered_qos import publisher_qos, reliable

DEFAULT_CLOCK_HZ = 100.0
"""``--clock`` without a value: /clock messages per second of wall time."""


@dataclass(frozen=True, slots=True)
class PlayOptions:
    """Options of ``sideslip-play`` (see its ``--help``).

    Attributes:
        bag: rosbag2 directory or bare .mcap file.
        rate: playback speed factor (> 0; 2 plays twice as fast).
        clock_hz: publish /clock with bag time at this rate [Hz]; None: no /clock.
        loop: start again at the end of the bag, until stopped.
        topics: bag topics to play; empty: all.
        remaps: (bag topic, published topic) pairs.
        wait_subscribers_s: wait up to this long [s] before starting until the awaited
            publishers have matched ``wait_count`` subscriptions each (0: do not wait).
        wait_topics: the published topics (after ``remaps``) to wait for; empty: all.
        wait_count: subscriptions each awaited publisher must have matched (>= 1).
        reliable: publish every topic reliable with a deep keep-last history.
        delay_s: wait this long [s] before the first message (after the wait above).
    """

    bag: Path
    rate: float = 1.0
    clock_hz: float | None = None
    loop: bool = False
    topics: tuple[str, ...] = ()
    remaps: tuple[tuple[str, str], ...] = ()
    wait_subscribers_s: float = 0.0
    wait_topics: tuple[str, ...] = ()
    wait_count: int = 1
    reliable: bool = False
    delay_s: float = 0.0


@dataclass(frozen=True, slots=True)
class PlayTopic:
    """One topic to publish.

    Attributes:
        bag_topic: name in the bag.
        out_topic: name to publish on (after ``--remap``).
        msgtype: ROS 2 type name.
        qos: publisher QoS.
        count: messages on it in one pass.
    """

    bag_topic: str
    out_topic: str
    msgtype: str
    qos: QosSpec
    count: int


@dataclass(frozen=True, slots=True)
class PlayPlan:
    """The topics to publish, those to wait for, and notes about choices made for the user.

    Attributes:
        topics: every topic to publish.
        wait_topics: published names of the topics whose subscribers are awaited before
            the first message (empty when the player does not wait).
        notes: choices made for the user, printed before playing.
    """

    topics: tuple[PlayTopic, ...]
    notes: tuple[str, ...] = ()
    wait_topics: tuple[str, ...] = ()


def plan_playback(source: BagSource, options: PlayOptions) -> PlayPlan:
    """Check ``options`` against the bag and choose every publisher.

    Raises:
        OptionError: ``--topics`` or a ``--remap`` source names a topic the bag lacks;
            ``--wait-topics`` names a topic that is not played; ``--wait-topics`` or
            ``--wait-count`` without a ``--wait-subscribers`` timeout.
        UnknownTypeError: a topic to play has a type with no Python message class.
    """
    in_bag = sorted(source.topics)
    for topic in options.topics:
        if topic not in source.topics:
            msg = f"--topics {topic}: not in {source.path} (its topics: {', '.join(in_bag)})"
            raise OptionError(msg)
    remaps = dict(options.remaps)
    for old in remaps:
        if old not in source.topics:
            msg = f"--remap {old}:=...: {old} is not in {source.path} (its topics: {in_bag})"
            raise OptionError(msg)

    chosen = options.topics or tuple(in_bag)
    planned: list[PlayTopic] = []
    notes: list[str] = []
    for name in chosen:
        info = source.topics[name]
        out = remaps.get(name, name)
        if options.clock_hz is not None and out == contract.CLOCK:
            notes.append(f"not playing the bag's {name}: --clock publishes {contract.CLOCK}")
            continue
        message_class(info.msgtype)  # raises UnknownTypeError before anything starts
        spec = publisher_qos(info.offers)
        if spec is None:
            spec = contract_qos.TOPIC_QOS.get(name, contract_qos.RELIABLE)
        if options.reliable:
            spec = reliable(spec)
        planned.append(PlayTopic(name, out, info.msgtype, spec, info.count))
    return PlayPlan(tuple(planned), tuple(notes), _wait_topics(options, planned))


def _wait_topics(options: PlayOptions, planned: list[PlayTopic]) -> tuple[str, ...]:
    """The published names to wait for; refuses wait options that would do nothing."""
    if options.wait_subscribers_s <= 0:
        if options.wait_topics or options.wait_count != 1:
            msg = "--wait-topics and --wait-count need --wait-subscribers S (S > 0)"
            raise OptionError(msg)
        return ()
    if options.wait_count < 1:
        msg = f"--wait-count must be >= 1, got {options.wait_count}"
        raise OptionError(msg)
    published = [t.out_topic for t in planned]
    for topic in options.wait_topics:
        if topic not in published:
            msg = (
                f"--wait-topics {topic}: not played from {options.bag} "
                f"(played: {', '.join(published) or 'nothing'})"
            )
            raise OptionError(msg)
    return tuple(dict.fromkeys(options.wait_topics)) or tuple(published)
