"""Finish a bag whose recorder was killed: ``sideslip-record --reindex DIR``.

A recorder killed without a chance to close the bag (SIGKILL, OOM killer, power to the
process cut) leaves a directory whose .mcap file has the chunks flushed so far but no
summary and no footer, and (since the recorder writes one, :mod:`.bagmeta`) only a
provisional metadata.yaml. rosbags refuses such a file: its MCAP reader needs the footer.

:func:`reindex` reads each .mcap file of the directory record by record, up to its
first damaged record (a chunk cut short or failing its CRC), and:

* a file that rosbags already reads whole is left as it is;
* any other file is rewritten: its readable messages, byte for byte with their log
  times, topics, types, message definitions and offered QoS, go into a new, complete
  .mcap file of the same name; the original is kept beside it as
  ``<name>.mcap.damaged`` (never deleted: it may hold more than we could read);

then it writes metadata.yaml as a finished recording has it (rosbag2 version 9,
storage ``mcap``, per-topic counts, start time, duration, the files, and the
``custom_data`` from the provisional metadata or the files), and checks that rosbags
opens the directory. Nothing here imports rclpy.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Final

import yaml

from sideslip_msgs_py.bag import MCAP_MAGIC, ROSBAG2_VERSION
from sideslip_msgs_py.errors import BagError, BagExistsError, NotABagError

from .bagmeta import (
    IN_PROGRESS_KEY,
    METADATA_NAME,
    FileEntry,
    RecorderTag,
    TopicEntry,
    custom_data_of,
    metadata_document,
    read_metadata,
    write_metadata,
)

DAMAGED_SUFFIX: Final = ".damaged"
"""Appended to the name of a .mcap file that was rewritten (the original, kept)."""

TMP_PREFIX: Final = ".reindex-"
"""Prefix of the temporary directory (inside the bag) that a rewrite is written in."""


@dataclass(frozen=True, slots=True)
class ScannedChannel:
    """One MCAP channel with its schema, as found in the file.

    Attributes:
        topic: topic name.
        msgtype: ROS 2 type name (the schema name); '' when the file has no schema for it.
        serialization_format: message encoding ('cdr').
        offered_qos_yaml: the channel's ``offered_qos_profiles`` (rosbag2 YAML text).
        schema_encoding: 'ros2msg' or 'ros2idl'; '' without a schema.
        schema_data: the message definition text.
    """

    topic: str
    msgtype: str
    serialization_format: str
    offered_qos_yaml: str
    schema_encoding: str
    schema_data: str

    @property
    def key(self) -> tuple[str, str, str, str]:
        """What makes one rosbag2 connection: topic, type, encoding and offered QoS."""
        return (self.topic, self.msgtype, self.serialization_format, self.offered_qos_yaml)


@dataclass
class McapScan:
    """What one .mcap file holds, read record by record (see :func:`scan_mcap`).

    Attributes:
        file: the file.
        channels: channel id → channel.
        counts: channel id → messages read.
        start_ns: log time [ns] of the first message read (0 when none).
        end_ns: log time [ns] of the last message read (0 when none).
        compression: chunk compression ('zstd', 'lz4' or '' for none).
        custom_data: rosbag2 ``custom_data`` from the file's ``rosbag2`` metadata
            record (a closed recording has one), else None.
        damage: where and why reading stopped before the footer; None for a whole file.
    """

    file: Path
    channels: dict[int, ScannedChannel] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)
    start_ns: int = 0
    end_ns: int = 0
    compression: str = ""
    custom_data: dict[str, str] | None = None
    damage: str | None = None

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())


@dataclass(frozen=True)
class ReindexResult:
    """What :func:`reindex` did.

    Attributes:
        path: the bag directory.
        files: its .mcap files, as listed in metadata.yaml.
        topic_counts: messages per topic in the finished bag.
        start_ns: log time [ns] of its first message (0 when none).
        end_ns: log time [ns] of its last message (0 when none).
        kept_damaged: originals of the rewritten files (``*.mcap.damaged``).
        notes: one line per thing the user should know (where a file was cut, what
            could not be carried over).
    """

    path: Path
    files: tuple[str, ...]
    topic_counts: dict[str, int]
    start_ns: int
    end_ns: int
    kept_damaged: tuple[Path, ...] = ()
    notes: tuple[str, ...] = ()

    @property
    def message_count(self) -> int:
        return sum(self.topic_counts.values())


# --- reading ----------------------------------------------------------------------------------


class _Records:
    """The records of one MCAP stream in file order, chunks opened, up to the first damage.

    A chunk is opened whole (and its CRC checked when it has one) before any of its
    records is given out, so a damaged chunk gives nothing. After iterating,
    :attr:`damage` says where and why reading stopped early (None: it reached the footer).
    """

    def __init__(self, stream: IO[bytes], file: Path) -> None:
        self._stream = stream
        self._file = file
        self.damage: str | None = None
        self.compression = ""

    def __iter__(self) -> Iterator[Any]:
        from mcap.exceptions import EndOfFile
        from mcap.records import Chunk, Footer
        from mcap.stream_reader import StreamReader, breakup_chunk

        where = 0
        try:
            for record in StreamReader(self._stream, emit_chunks=True).records:
                if isinstance(record, Chunk):
                    self.compression = self.compression or record.compression
                    records = breakup_chunk(record, validate_crc=True)
                    where = self._stream.tell()
                    yield from records
                    continue
                where = self._stream.tell()
                yield record
                if isinstance(record, Footer):
                    return
        except EndOfFile:
            self.damage = f"{self._file}: ends at byte {where} without summary and footer"
        except Exception as err:  # any decoding failure marks the end of the readable part
            self.damage = (
                f"{self._file}: unreadable after byte {where} ({type(err).__name__}: {err})"
            )
        else:
            self.damage = f"{self._file}: ends at byte {where} without a footer"


def scan_mcap(file: Path) -> McapScan:
    """Read ``file`` record by record: its channels, message counts, time span and
    custom_data, up to its first damaged record (see :attr:`McapScan.damage`).
    """
    from mcap.records import Channel, Message, Metadata, Schema

    scan = McapScan(file)
    schemas: dict[int, Any] = {}
    start_ns, end_ns = 2**63 - 1, 0
    with file.open("rb") as stream:
        records = _Records(stream, file)
        for record in records:
            if isinstance(record, Message):
                if record.channel_id not in scan.channels:
                    continue  # its channel record was lost: cannot be carried over
                scan.counts[record.channel_id] += 1
                start_ns = min(start_ns, record.log_time)
                end_ns = max(end_ns, record.log_time)
            elif isinstance(record, Schema):
                schemas.setdefault(record.id, record)
            elif isinstance(record, Channel) and record.id not in scan.channels:
                schema = schemas.get(record.schema_id)
                scan.channels[record.id] = ScannedChannel(
                    record.topic,
                    schema.name if schema else "",
                    record.message_encoding,
                    record.metadata.get("offered_qos_profiles", ""),
                    schema.encoding if schema else "",
                    schema.data.decode() if schema else "",
                )
                scan.counts.setdefault(record.id, 0)
            elif isinstance(record, Metadata) and record.name == "rosbag2":
                scan.custom_data = _custom_data(record.metadata.get("serialized_metadata", ""))
    if scan.message_count:
        scan.start_ns, scan.end_ns = start_ns, end_ns
    scan.compression = records.compression
    scan.damage = records.damage
    return scan


def _custom_data(serialized_metadata: str) -> dict[str, str] | None:
    try:
        info = yaml.safe_load(serialized_metadata)
    except yaml.YAMLError:
        return None
    return (custom_data_of(info) or None) if isinstance(info, dict) else None


def _rosbags_reads(path: Path) -> str | None:
    """None when rosbags opens ``path`` (a .mcap file or a bag directory), else why not."""
    from rosbags.rosbag2 import Reader

    try:
        with Reader(path):
            return None
    except Exception as err:  # ReaderError, KeyError, ...
        return f"{type(err).__name__}: {err}"


# --- types ------------------------------------------------------------------------------------


def _definition(channel: ScannedChannel) -> tuple[str, str]:
    """(message definition, RIHS01 hash) of a channel's type, as rosbags checks them.

    The hash is computed from the definition in the file, as rosbags' AnyReader does
    when it verifies it; without one (a lost schema), from the Jazzy typestore.

    Raises:
        BagError: no definition in the file and the type is not a Jazzy type.
    """
    from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

    if channel.schema_data and channel.msgtype:
        store = get_typestore(Stores.EMPTY)
        sep = "=" * 80 + "\n"
        if channel.schema_encoding == "ros2msg":
            store.register(get_types_from_msg(channel.schema_data, channel.msgtype))
        elif channel.schema_data.startswith(f"{sep}IDL: "):  # rosbag2's bundle of .idl files
            for part in channel.schema_data.split(sep)[1:]:
                store.register(get_types_from_idl(part.split("\n", 1)[1]))
        else:
            store.register(get_types_from_idl(channel.schema_data))
        return channel.schema_data, store.hash_rihs01(channel.msgtype)
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    try:
        msgdef, _ = jazzy.generate_msgdef(channel.msgtype, ros_version=2)
        return msgdef, jazzy.hash_rihs01(channel.msgtype)
    except Exception:
        msg = (
            f"topic {channel.topic}: the file holds no definition of its type "
            f"{channel.msgtype!r} and it is not a ROS 2 Jazzy type"
        )
        raise BagError(msg) from None


def _qos(channel: ScannedChannel) -> tuple[Any, ...]:
    from rosbags.rosbag2.metadata import parse_qos

    return tuple(parse_qos(channel.offered_qos_yaml))


# --- rewriting --------------------------------------------------------------------------------


def _rewrite(bag_dir: Path, scan: McapScan, custom_data: Mapping[str, str]) -> Path:
    """Write ``scan.file``'s readable messages into a new, complete file of the same name.

    The original is renamed to ``<name>.mcap.damaged`` (or ``.damaged.1``, ... when
    taken) only once the new file is complete; returns the original's new path.
    """
    from mcap.records import Message
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

    tmp = bag_dir / f"{TMP_PREFIX}{scan.file.stem}"
    if tmp.exists():
        shutil.rmtree(tmp)  # ours, left by an interrupted reindex
    writer = Writer(tmp, version=ROSBAG2_VERSION, storage_plugin=StoragePlugin.MCAP)
    if scan.compression == "zstd":
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    for key, value in custom_data.items():
        writer.set_custom_data(key, value)  # also into the file's rosbag2 metadata record
    writer.open()
    try:
        conns: dict[int, Any] = {}
        by_key: dict[tuple[str, str, str, str], Any] = {}
        for cid, channel in scan.channels.items():
            if channel.key not in by_key:
                msgdef, rihs01 = _definition(channel)
                by_key[channel.key] = writer.add_connection(
                    channel.topic,
                    channel.msgtype,
                    msgdef=msgdef,
                    rihs01=rihs01,
                    serialization_format=channel.serialization_format,
                    offered_qos_profiles=list(_qos(channel)),
                )
            conns[cid] = by_key[channel.key]
        with scan.file.open("rb") as stream:
            for record in _Records(stream, scan.file):
                if isinstance(record, Message) and record.channel_id in conns:
                    writer.write(conns[record.channel_id], record.log_time, record.data)
        writer.close()
    except BaseException:
        writer.abort()
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    kept = _free_name(scan.file.with_name(scan.file.name + DAMAGED_SUFFIX))
    scan.file.rename(kept)
    (tmp / f"{tmp.name}.mcap").rename(scan.file)
    shutil.rmtree(tmp)
    return kept


def _free_name(path: Path) -> Path:
    if not path.exists():
        return path
    n = 1
    while path.with_name(f"{path.name}.{n}").exists():
        n += 1
    return path.with_name(f"{path.name}.{n}")


# --- the bag ----------------------------------------------------------------------------------


def _mcap_files(path: Path) -> list[Path]:
    if not path.exists():
        msg = f"{path}: no such bag directory"
        raise NotABagError(msg)
    if not path.is_dir():
        msg = f"{path} is not a directory; --reindex takes a bag directory (the .mcap's folder)"
        raise NotABagError(msg)
    files = sorted(p for p in path.glob("*.mcap") if p.is_file())
    if not files:
        msg = f"{path}: holds no .mcap file, so it is not an MCAP bag directory"
        raise NotABagError(msg)
    for file in files:
        with file.open("rb") as stream:
            if stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                msg = f"{file}: not an MCAP file (bad magic bytes)"
                raise NotABagError(msg)
    return files


def _prior_custom_data(path: Path, *, force: bool) -> dict[str, str]:
    """custom_data of an existing metadata.yaml that may be replaced.

    Raises:
        BagExistsError: without ``force``: a finished bag's metadata.yaml, one that is not
            rosbag2 metadata, or a recorder that is still writing the bag.
    """
    meta = path / METADATA_NAME
    if not meta.exists():
        return {}
    try:
        info = read_metadata(path)
    except NotABagError as err:
        if force:
            return {}
        msg = f"{err}; pass --force to replace it"
        raise BagExistsError(msg) from None
    custom = custom_data_of(info)
    marker = custom.pop(IN_PROGRESS_KEY, None)
    if force:
        return custom
    if marker is None:
        msg = f"{meta} exists: {path} is a finished bag; pass --force to write its metadata again"
        raise BagExistsError(msg)
    tag = RecorderTag.parse(marker)
    if tag is not None and tag.still_recording():
        msg = (
            f"{path} is still being recorded (recorder pid {tag.pid}); stop it first, or "
            "pass --force if that process is not the recorder"
        )
        raise BagExistsError(msg)
    return custom


def _topics(scans: list[McapScan]) -> list[TopicEntry]:
    """One entry per connection (topic, type, encoding, QoS), counts summed over files."""
    order: list[tuple[str, str, str, str]] = []
    channels: dict[tuple[str, str, str, str], ScannedChannel] = {}
    counts: dict[tuple[str, str, str, str], int] = {}
    for scan in scans:
        for cid, channel in scan.channels.items():
            if channel.key not in channels:
                order.append(channel.key)
                channels[channel.key] = channel
            counts[channel.key] = counts.get(channel.key, 0) + scan.counts.get(cid, 0)
    return [
        TopicEntry(
            channels[key].topic,
            channels[key].msgtype,
            _definition(channels[key])[1],
            _qos(channels[key]),
            counts[key],
            channels[key].serialization_format,
        )
        for key in order
    ]


def reindex(path: str | Path, *, force: bool = False) -> ReindexResult:
    """Make the bag directory ``path`` a finished rosbag2 bag (see the module docstring).

    Args:
        path: a bag directory holding one or more .mcap files.
        force: replace a finished bag's metadata.yaml too (and ignore a recorder that
            seems to be still writing the bag).

    Raises:
        NotABagError: ``path`` is not a directory, holds no .mcap file, or one that is
            not MCAP.
        BagExistsError: metadata.yaml of a finished bag, or of a bag still being recorded,
            and ``force`` is false.
        BagError: a type without definition, or rosbags cannot open the result.
    """
    path = Path(path)
    files = _mcap_files(path)
    custom = _prior_custom_data(path, force=force)
    scans = [scan_mcap(file) for file in files]
    for scan in scans:
        custom.update(scan.custom_data or {})
    notes: list[str] = []
    kept: list[Path] = []
    for i, scan in enumerate(scans):
        why = scan.damage or _rosbags_reads(scan.file)
        if why is None:
            continue
        original = _rewrite(path, scan, custom)
        kept.append(original)
        notes.append(
            f"{why}; its {scan.message_count} readable messages rewritten to "
            f"{scan.file.name}, original kept as {original.name}"
        )
        scans[i] = rescan = scan_mcap(scan.file)
        if rescan.damage is not None or rescan.message_count != scan.message_count:
            msg = f"{scan.file}: rewritten file does not read back whole ({rescan.damage})"
            raise BagError(msg)

    topics = _topics(scans)
    entries = [FileEntry(s.file.name, s.message_count, s.start_ns, s.end_ns) for s in scans]
    write_metadata(path, metadata_document(topics, entries, custom))
    if (why := _rosbags_reads(path)) is not None:
        msg = f"{path}: metadata.yaml written, but rosbags cannot open the bag: {why}"
        raise BagError(msg)

    counts: dict[str, int] = {}
    for topic in topics:
        counts[topic.name] = counts.get(topic.name, 0) + topic.count
    with_messages = [s for s in scans if s.message_count]
    return ReindexResult(
        path,
        tuple(entry.path for entry in entries),
        counts,
        min((s.start_ns for s in with_messages), default=0),
        max((s.end_ns for s in with_messages), default=0),
        tuple(kept),
        tuple(notes),
    )
