"""Finish a bag whose recorder was killed: ``sideslip-record --reindex DIR``.

A recorder killed without a chance to close the bag (SIGKILL, OOM killer, power to the
process cut) leaves a directory whose .mcap file has the chunks flushed so far but no
summary and no footer, and (since the recorder writes one, :mod:`.bagmeta`) only a
provisional metadata.yaml. rosbags refuses such a file: its MCAP reader needs the footer.

:func:`reindex` reads each .mcap file of the directory record by record, up to its
first damaged record (a chunk cut short or failing its CRC; :mod:`.mcapscan`), and:

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
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

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
from .mcapscan import McapRecords, McapScan, ScannedChannel, scan_mcap

DAMAGED_SUFFIX: Final = ".damaged"
"""Appended to the name of a .mcap file that was rewritten (the original, kept)."""

TMP_PREFIX: Final = ".reindex-"
"""Prefix of the temporary directory (inside the bag) that a rewrite is written in."""


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
            for record in McapRecords(stream, scan.file):
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
