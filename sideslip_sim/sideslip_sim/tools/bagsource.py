"""Read a bag for playback: its topics with their offered QoS, and its raw messages.

Accepts a rosbag2 directory (metadata.yaml + storage files) or a bare .mcap file, read
with rosbags; messages come in log-time order. An MCAP file that rosbags cannot open
(a recorder killed before writing the summary, a copy cut short) is read record by
record up to the first damaged record: :attr:`BagSource.truncated` says so and
:attr:`BagSource.notes` says where it stopped. That readable part is held in memory
(sorted by log time); an intact bag is streamed from disk on every pass.
"""

from __future__ import annotations

from collections.abc import Collection, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

from sideslip_msgs_py.errors import BagError, NotABagError

from .offers import OfferedQos, parse_offered_qos_yaml

MCAP_MAGIC = b"\x89MCAP0\r\n"


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


class BagMessage(NamedTuple):
    """One serialised message: topic, log time [ns] and its CDR bytes."""

    topic: str
    log_time_ns: int
    data: bytes


@dataclass(frozen=True)
class BagSource:
    """A bag opened for playback (see :func:`open_bag`).

    Attributes:
        path: the bag directory or .mcap file.
        topics: every topic of the bag by name.
        start_ns: log time [ns] of the bag's first message (0 when it has none).
        end_ns: log time [ns] of the bag's last message (0 when it has none).
        truncated: the bag is damaged; only its readable part plays.
        notes: what was not read verbatim (where a truncated file stops).
    """

    path: Path
    topics: dict[str, BagTopic]
    start_ns: int
    end_ns: int
    truncated: bool = False
    notes: tuple[str, ...] = ()
    _readable: list[BagMessage] | None = field(default=None, repr=False)

    def messages(self, topics: Collection[str]) -> Iterator[BagMessage]:
        """Messages on ``topics`` in log-time order (one pass; call again to repeat).

        Raises:
            BagError: the file became unreadable part way (names the path and position).
        """
        wanted = set(topics)
        if self._readable is not None:
            yield from (m for m in self._readable if m.topic in wanted)
            return
        from rosbags.rosbag2 import Reader

        count = 0
        try:
            with Reader(self.path) as reader:
                conns = [c for c in reader.connections if c.topic in wanted]
                if not conns:
                    return
                for conn, t_ns, data in reader.messages(connections=conns):
                    yield BagMessage(conn.topic, t_ns, data)
                    count += 1
        except Exception as err:  # rosbags' ReaderError, zstd errors, struct errors, ...
            msg = f"{self.path}: unreadable after {count} messages ({type(err).__name__}: {err})"
            raise BagError(msg) from err


def open_bag(path: str | Path) -> BagSource:
    """Open ``path`` for playback and read its topics.

    Raises:
        NotABagError: nothing there, a directory without metadata.yaml, a file that is
            not MCAP, or a bag that neither rosbags nor the record-by-record reader can
            read.
    """
    from rosbags.rosbag2 import Reader

    path = Path(path)
    if not path.exists():
        msg = f"{path}: no such bag (expected a rosbag2 directory or an .mcap file)"
        raise NotABagError(msg)
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        msg = f"{path}: directory has no metadata.yaml, so it is not a rosbag2 bag"
        raise NotABagError(msg)
    if path.is_file() and not _is_mcap(path):
        msg = f"{path}: not an MCAP file (bad magic bytes); expected a bag"
        raise NotABagError(msg)
    try:
        with Reader(path) as reader:
            found: dict[str, BagTopic] = {}
            for conn in reader.connections:
                offers = tuple(OfferedQos.from_rosbags(q) for q in conn.ext.offered_qos_profiles)
                known = found.get(conn.topic)
                if known is not None and known.msgtype != conn.msgtype:
                    msg = f"{path}: topic {conn.topic} is recorded with two types"
                    raise NotABagError(msg)
                found[conn.topic] = BagTopic(
                    conn.topic,
                    conn.msgtype,
                    (known.count if known else 0) + conn.msgcount,
                    (known.offers if known else ()) + offers,
                )
            # rosbags' end_time is one past the last message; an empty bag has neither.
            if reader.message_count == 0:
                return BagSource(path, found, 0, 0)
            return BagSource(path, found, reader.start_time, reader.end_time - 1)
    except NotABagError:
        raise
    except Exception as err:  # rosbags raises ReaderError, KeyError, ValueError, ...
        files = [path] if path.is_file() else sorted(path.glob("*.mcap"))
        if not files or not all(_is_mcap(f) for f in files):
            msg = f"{path}: cannot read bag: {type(err).__name__}: {err}"
            raise NotABagError(msg) from None
        source = _read_records(path, files)
        note = f"{path}: rosbags could not open it ({err}); read it record by record"
        return BagSource(
            source.path,
            source.topics,
            source.start_ns,
            source.end_ns,
            truncated=True,
            notes=(note, *source.notes),
            _readable=source._readable,
        )


def _is_mcap(file: Path) -> bool:
    try:
        with file.open("rb") as stream:
            return stream.read(len(MCAP_MAGIC)) == MCAP_MAGIC
    except OSError:
        return False


def _read_records(path: Path, files: list[Path]) -> BagSource:
    """Every complete message record of ``files``, up to the first damaged record."""
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader

    messages: list[BagMessage] = []
    types: dict[str, str] = {}
    offers: dict[str, tuple[OfferedQos, ...]] = {}
    notes: list[str] = []
    for file in files:
        schemas: dict[int, str] = {}
        channels: dict[int, str] = {}
        count = 0
        with file.open("rb") as stream:
            try:
                for record in StreamReader(stream, skip_magic=False).records:
                    if isinstance(record, Message):
                        messages.append(
                            BagMessage(channels[record.channel_id], record.log_time, record.data)
                        )
                        count += 1
                    elif isinstance(record, Channel):
                        channels[record.id] = record.topic
                        types.setdefault(record.topic, schemas.get(record.schema_id, ""))
                        text = record.metadata.get("offered_qos_profiles", "")
                        try:
                            offers.setdefault(record.topic, tuple(parse_offered_qos_yaml(text)))
                        except ValueError as err:
                            notes.append(f"{file}: {record.topic}: {err}; using default QoS")
                            offers.setdefault(record.topic, ())
                    elif isinstance(record, Schema):
                        schemas[record.id] = record.name
            except Exception as err:  # any decoding failure marks the end of readable data
                notes.append(
                    f"{file}: unreadable after {count} messages at byte {stream.tell()} "
                    f"({type(err).__name__}: {err}); playing the complete records before it"
                )
    messages.sort(key=lambda m: m.log_time_ns)  # stable: equal times keep file order
    counts: dict[str, int] = dict.fromkeys(types, 0)
    for m in messages:
        counts[m.topic] += 1
    found = {t: BagTopic(t, types[t], counts[t], offers.get(t, ())) for t in types}
    start = messages[0].log_time_ns if messages else 0
    end = messages[-1].log_time_ns if messages else 0
    return BagSource(path, found, start, end, notes=tuple(notes), _readable=messages)
