"""What ``sideslip-play`` will do, decided before any DDS entity exists (no rclpy).

:func:`plan_playback` checks the options against the bag (topics and remaps that name
bag topics, message types that have a Python class) and picks each publisher's QoS:
the bag's recorded offers (:func:`~.offers.publisher_qos`), else the contract QoS of a
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
from .cli import message_class
from .errors import OptionError
from .offers import publisher_qos, reliable

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
        wait_subscribers_s: wait up to this long [s] for every publisher to match a
            subscription before starting (0: do not wait).
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
    """The topics to publish and notes about choices made for the user."""

    topics: tuple[PlayTopic, ...]
    notes: tuple[str, ...] = ()


def plan_playback(source: BagSource, options: PlayOptions) -> PlayPlan:
    """Check ``options`` against the bag and choose every publisher.

    Raises:
        OptionError: ``--topics`` or a ``--remap`` source names a topic the bag lacks.
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
    return PlayPlan(tuple(planned), tuple(notes))
