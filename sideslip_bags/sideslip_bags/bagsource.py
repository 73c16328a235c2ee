"""Read a bag for playback: its topics with their offered QoS, and its raw messages.

Reading is :func:`sideslip_msgs_py.bag.open_raw_bag`'s, shared with ``read_bag``: a
rosbag2 directory or a bare .mcap file, messages in log-time order, an intact bag
streamed from disk on every pass, and a damaged MCAP file read record by record up to
its first damaged record (:attr:`BagSource.truncated` says so and
:attr:`BagSource.notes` says where it stopped). This module adds the player's view of
the offered QoS (:class:`~.offered_qos.OfferedQos`).
"""

from __future__ import annotations

from collections.abc import Collection, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from sideslip_msgs_py.bag import RawBag, RawMessage, RawTopic, open_raw_bag

from .offered_qos import OfferedQos, parse_offered_qos_yaml

BagMessage = RawMessage
"""One serialised message: topic, log time [ns] and its CDR bytes."""


@dataclass(frozen=True, slots=True)
class BagTopic:
    """One topic of a bag.

    Attributes:
        name: topic name as recorded.
        msgtype: ROS 2 type name ('pkg/msg/Name').
        count: messages on it (the readable ones, for a truncated bag).
        offers: the QoS profiles its publishers offered when it was recorded.
    """

    name: str
    msgtype: str
    count: int
    offers: tuple[OfferedQos, ...] = ()


@dataclass(frozen=True)
class BagSource:
    """A bag opened for playback (see :func:`open_bag`).

    Attributes:
        path: the bag directory or .mcap file.
        topics: every topic of the bag by name.
        start_ns: log time [ns] of the bag's first message (0 when it has none).
        end_ns: log time [ns] of the bag's last message (0 when it has none).
        truncated: the bag is damaged; only its readable part plays.
        notes: what was not read verbatim (where a truncated file stops, QoS that could
            not be read).
    """

    path: Path
    topics: dict[str, BagTopic]
    start_ns: int
    end_ns: int
    truncated: bool = False
    notes: tuple[str, ...] = ()
    _raw: RawBag = field(kw_only=True, repr=False)

    def messages(self, topics: Collection[str]) -> Iterator[BagMessage]:
        """Messages on ``topics`` in log-time order (one pass; call again to repeat).

        Raises:
            BagError: the file became unreadable part way (names the path and position).
        """
        return self._raw.messages(topics)


def open_bag(path: str | Path) -> BagSource:
    """Open ``path`` for playback and read its topics.

    Raises:
        NotABagError: nothing there, a directory without metadata.yaml, a file that is
            not MCAP, or a bag that neither rosbags nor the record-by-record reader can
            read.
        WrongTopicTypeError: a topic is recorded with two message types.
    """
    raw = open_raw_bag(path)
    notes = list(raw.notes)
    found = {
        name: BagTopic(name, topic.msgtype, topic.count, _offers(raw.path, topic, notes))
        for name, topic in raw.topics.items()
    }
    return BagSource(
        raw.path, found, raw.start_ns, raw.end_ns, raw.truncated, tuple(notes), _raw=raw
    )


def _offers(path: Path, topic: RawTopic, notes: list[str]) -> tuple[OfferedQos, ...]:
    """The topic's offered QoS; none (so the contract or default QoS) when unreadable."""
    if topic.offered_qos_yaml is None:
        return tuple(OfferedQos.from_rosbags(q) for q in topic.offered_qos)
    try:
        return tuple(parse_offered_qos_yaml(topic.offered_qos_yaml))
    except ValueError as err:
        notes.append(f"{path}: {topic.name}: {err}; using default QoS")
        return ()
