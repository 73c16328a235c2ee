"""Read an MCAP file record by record, up to its first damage (for ``--reindex``).

A recorder killed without closing its bag leaves an .mcap file with the chunks flushed
so far but no summary and no footer; a file can also end inside a chunk. Readers that
start from the summary (rosbags) refuse such a file. :class:`McapRecords` walks the
records from the start instead, opening each chunk whole (CRC checked) before giving
out any of its records, and stops at the first damaged one; :func:`scan_mcap` gathers
what the readable part holds: channels with their schemas, message counts, time span,
compression and rosbag2 ``custom_data``. Nothing here imports rclpy.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import yaml

from .bagmeta import custom_data_of


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


class McapRecords:
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
        records = McapRecords(stream, file)
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
