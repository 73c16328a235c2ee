"""Raw bag reading: a bag's topics and serialised messages, intact or damaged.

:func:`open_raw_bag` opens a rosbag2 directory (metadata.yaml + .mcap) or a bare .mcap
file and gives a :class:`RawBag`: every topic with its type and offered QoS, and its
messages as CDR bytes in log-time order, streamed from disk by rosbags. An MCAP bag that
rosbags cannot open (a recorder killed before writing the summary, a copy cut short) is
read record by record with the ``mcap`` reader, up to each file's first damaged record,
and marked ``truncated`` with notes saying where it stopped. Nothing is decoded here:
:func:`sideslip_msgs_py.bag.read_bag` decodes and aligns the samples, and the player
(``sideslip_bags.bagsource``) republishes the bytes as they are.

The run's parameters travel in rosbag2's ``custom_data``, which :meth:`RawBag.custom_data`
reads from metadata.yaml or, for a bare .mcap, from its ``rosbag2`` metadata record.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Collection, Iterator
from dataclasses import dataclass, field
from operator import attrgetter
from pathlib import Path
from typing import TYPE_CHECKING, Final, NamedTuple

from .errors import BagError, NotABagError, WrongTopicTypeError

if TYPE_CHECKING:
    from rosbags.interfaces import Qos

MCAP_MAGIC: Final = b"\x89MCAP0\r\n"


class RawMessage(NamedTuple):
    """One serialised message as stored: topic, log (bag) time [ns] and its CDR bytes."""

    topic: str
    log_time_ns: int
    data: bytes


@dataclass(frozen=True, slots=True)
class RawTopic:
    """One topic of a bag, as recorded.

    Attributes:
        name: topic name.
        msgtype: ROS 2 type name ('pkg/msg/Name'); '' when a damaged file lost its schema.
        count: messages on it (the readable ones, for a truncated bag).
        offered_qos: its publishers' offered QoS profiles, as rosbags reads them from
            the bag's metadata (``rosbags.interfaces.Qos``); empty for a bag read record
            by record, which has ``offered_qos_yaml`` instead.
        offered_qos_yaml: for a bag read record by record, the ``offered_qos_profiles``
            text (rosbag2 YAML, unparsed) of the topic's first MCAP channel; None otherwise.
    """

    name: str
    msgtype: str
    count: int
    offered_qos: tuple[Qos, ...] = ()
    offered_qos_yaml: str | None = None


@dataclass(frozen=True)
class RawBag:
    """A bag opened by :func:`open_raw_bag`: its topics, time span and serialised messages.

    Attributes:
        path: the bag directory or .mcap file.
        topics: every topic of the bag by name (also those without messages).
        start_ns: log time [ns] of the first message (0 when it has none).
        end_ns: log time [ns] of the last message (0 when it has none).
        truncated: the bag is damaged; only its readable part is there.
        notes: what was not read verbatim (why rosbags could not read it, where a file
            stops).
    """

    path: Path
    topics: dict[str, RawTopic]
    start_ns: int
    end_ns: int
    truncated: bool = False
    notes: tuple[str, ...] = ()
    _readable: list[RawMessage] | None = field(default=None, repr=False)
    _custom_data: dict[str, str] | None = field(default=None, repr=False)

    def messages(self, topics: Collection[str] | None = None) -> Iterator[RawMessage]:
        """Messages on ``topics`` (all when None) in log-time order.

        One pass: call again to repeat. An intact bag is streamed from disk on each pass;
        the readable part of a damaged one is held in memory.

        Raises:
            BagError: the file became unreadable part way (names the path and position).
        """
        wanted = None if topics is None else set(topics)
        if self._readable is not None:
            yield from (m for m in self._readable if wanted is None or m.topic in wanted)
            return
        for topic, log_time_ns, data in self._stream(wanted):
            yield RawMessage(topic, log_time_ns, data)

    def _stream(self, wanted: Collection[str] | None) -> Iterator[tuple[str, int, bytes]]:
        """An intact bag's messages on ``wanted`` (all when None), read from disk.

        Plain tuples: :func:`read_messages_by_topic` takes these directly, which saves
        building a :class:`RawMessage` per message (about a tenth of
        :func:`~sideslip_msgs_py.bag.read_bag`'s time).
        """
        from rosbags.rosbag2 import Reader

        count = 0
        try:
            with Reader(self.path) as reader:
                conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
                if not conns:
                    return
                for conn, t_ns, data in reader.messages(connections=conns):
                    yield conn.topic, t_ns, data
                    count += 1
        except Exception as err:  # rosbags' ReaderError, zstd errors, struct errors, ...
            msg = f"{self.path}: unreadable after {count} messages ({type(err).__name__}: {err})"
            raise BagError(msg) from err

    def custom_data(self) -> dict[str, str] | None:
        """rosbag2's custom_data: from metadata.yaml, else from the .mcap's metadata record.

        Read from disk on each call, except for a damaged bare .mcap, whose metadata
        record the record-by-record read kept. None when the bag has none.
        """
        yaml_path = self.path / "metadata.yaml"
        if self.path.is_dir() and yaml_path.is_file():
            return _custom_data_from_yaml(yaml_path.read_text(encoding="utf-8"), yaml_path)
        if self.truncated:
            return self._custom_data
        return _mcap_custom_data(self.path)


def open_raw_bag(path: str | Path) -> RawBag:
    """Open a rosbag2 directory or a bare .mcap file and read its topics.

    The messages are not read here: an intact bag streams them from disk on each
    :meth:`RawBag.messages` pass. An MCAP bag that rosbags cannot open (a recorder killed
    before writing the summary, a copy cut short) is read record by record, in file
    order, up to each file's first damaged record; that readable part is held in memory,
    sorted by log time, with ``truncated`` set and ``notes`` saying where it stopped.

    A directory with .mcap files but no metadata.yaml (a recorder killed before it wrote
    one) is read the same way, with a note naming ``sideslip-record --reindex``.

    Raises:
        NotABagError: nothing there, a directory with neither metadata.yaml nor .mcap
            files, a file that is not MCAP, or a bag that neither rosbags nor the
            record-by-record reader can read.
        WrongTopicTypeError: a topic is recorded with two message types.
    """
    path = Path(path)
    if not path.exists():
        msg = f"{path}: no such bag (expected a rosbag2 directory or an .mcap file)"
        raise NotABagError(msg)
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        if not _storage_files(path):
            msg = f"{path}: directory has no metadata.yaml and no .mcap file: not a bag"
            raise NotABagError(msg)
        why = FileNotFoundError(
            "no metadata.yaml (a recorder stopped before writing it? "
            f"`sideslip-record --reindex {path}` writes it)"
        )
        return _read_records(path, why)
    if path.is_file() and not _starts_with_mcap_magic(path):
        msg = f"{path}: not an MCAP file (bad magic bytes); expected a bag"
        raise NotABagError(msg)
    try:
        return _open_with_rosbags(path)
    except BagError:
        raise
    except Exception as err:  # rosbags raises ReaderError, KeyError, ValueError, ...
        return _read_records(path, err)


def _open_with_rosbags(path: Path) -> RawBag:
    from rosbags.rosbag2 import Reader

    found: dict[str, RawTopic] = {}
    with Reader(path) as reader:
        for conn in reader.connections:
            known = found.get(conn.topic)
            if known is not None and known.msgtype != conn.msgtype:
                msg = f"{path}: topic {conn.topic} is recorded with two types"
                raise WrongTopicTypeError(msg)
            found[conn.topic] = RawTopic(
                conn.topic,
                conn.msgtype,
                (known.count if known else 0) + conn.msgcount,
                (known.offered_qos if known else ()) + tuple(conn.ext.offered_qos_profiles),
            )
        # rosbags' end_time is one past the last message; an empty bag has neither.
        if reader.message_count == 0:
            return RawBag(path, found, 0, 0)
        return RawBag(path, found, reader.start_time, reader.end_time - 1)


def _read_records(path: Path, why: BaseException) -> RawBag:
    """Every complete message record of the bag's .mcap files, up to each one's damage.

    ``why`` is what rosbags raised; it is the first note, or the error when the bag's
    storage is not MCAP.
    """
    from mcap.records import Channel, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader

    files = _storage_files(path)
    if not files or not all(_starts_with_mcap_magic(f) for f in files):
        msg = f"{path}: cannot read bag: {type(why).__name__}: {why}"
        raise NotABagError(msg) from None
    messages: list[RawMessage] = []
    types: dict[str, str] = {}
    offers: dict[str, str] = {}
    custom_data: dict[str, str] | None = None
    notes = [f"{path}: rosbags could not read it ({why}); read it record by record"]
    for file in files:
        schemas: dict[int, str] = {}
        channels: dict[int, str] = {}
        count = 0
        with file.open("rb") as stream:
            try:
                for record in StreamReader(stream).records:
                    if isinstance(record, Message):
                        topic = channels[record.channel_id]
                        messages.append(RawMessage(topic, record.log_time, record.data))
                        count += 1
                    elif isinstance(record, Channel):
                        channels[record.id] = record.topic
                        types.setdefault(record.topic, schemas.get(record.schema_id, ""))
                        offers.setdefault(
                            record.topic, record.metadata.get("offered_qos_profiles", "")
                        )
                    elif isinstance(record, Schema):
                        schemas[record.id] = record.name
                    elif isinstance(record, Metadata) and record.name == "rosbag2":
                        custom_data = _custom_data_from_yaml(
                            record.metadata.get("serialized_metadata", ""), file
                        )
            except Exception as err:  # any decoding failure marks the end of readable data
                notes.append(
                    f"{file}: unreadable after {count} messages at byte {stream.tell()} "
                    f"({type(err).__name__}: {err}); kept the complete records before it"
                )
    messages.sort(key=attrgetter("log_time_ns"))  # stable: equal times keep file order
    counts = Counter(m.topic for m in messages)
    found = {t: RawTopic(t, types[t], counts[t], offered_qos_yaml=offers[t]) for t in types}
    return RawBag(
        path,
        found,
        messages[0].log_time_ns if messages else 0,
        messages[-1].log_time_ns if messages else 0,
        # damaged, even where only the index or footer was lost
        truncated=True,
        notes=tuple(notes),
        _readable=messages,
        _custom_data=custom_data,
    )


def _storage_files(path: Path) -> list[Path]:
    """The .mcap files of a bag (a bare file or a directory's files, in order)."""
    if path.is_file():
        return [path]
    return sorted(path.glob("*.mcap"))


def _starts_with_mcap_magic(file: Path) -> bool:
    try:
        with file.open("rb") as stream:
            return stream.read(len(MCAP_MAGIC)) == MCAP_MAGIC
    except OSError:
        return False


def read_messages_by_topic(path: str | Path) -> tuple[RawBag, dict[str, list[bytes]]]:
    """The bag and all its messages per topic, in memory (every topic; log-time order
    within one). What :func:`sideslip_msgs_py.bag.read_bag` decodes.

    A bag whose summary rosbags reads but whose data is damaged further on is read
    again record by record, as one that rosbags cannot open.
    """
    path = Path(path)
    raw = open_raw_bag(path)
    try:
        return raw, _collect(raw)
    except BagError as err:
        raw = _read_records(path, err.__cause__ or err)
        return raw, _collect(raw)


def _collect(raw: RawBag) -> dict[str, list[bytes]]:
    data: dict[str, list[bytes]] = {topic: [] for topic in raw.topics}
    records = raw._readable if raw._readable is not None else raw._stream(None)
    for topic, _, payload in records:
        data[topic].append(payload)
    return data


def _custom_data_from_yaml(text: str, where: Path) -> dict[str, str] | None:
    import yaml

    try:
        doc = yaml.safe_load(text) or {}
    except yaml.YAMLError as err:
        msg = f"{where}: rosbag2 metadata is not valid YAML: {err}"
        raise NotABagError(msg) from None
    info = doc.get("rosbag2_bagfile_information", doc) if isinstance(doc, dict) else {}
    custom = info.get("custom_data") if isinstance(info, dict) else None
    return dict(custom) if isinstance(custom, dict) else None


def _mcap_custom_data(file: Path) -> dict[str, str] | None:
    """custom_data from the rosbag2 metadata record of an intact .mcap file."""
    from mcap.reader import make_reader

    with file.open("rb") as stream:
        for record in make_reader(stream).iter_metadata():
            if record.name == "rosbag2":
                return _custom_data_from_yaml(record.metadata.get("serialized_metadata", ""), file)
    return None


__all__ = [
    "MCAP_MAGIC",
    "RawBag",
    "RawMessage",
    "RawTopic",
    "open_raw_bag",
    "read_messages_by_topic",
]
