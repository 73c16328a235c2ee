"""Write and read sample bags: rosbag2 directories (metadata.yaml + .mcap) or bare .mcap.

Layout of a bag written here (what ``ros2 bag info/play`` and rosbags accept;
:func:`open_writer` sets up this one and the recorder's alike):

* rosbag2 metadata version 9, storage ``mcap``, ROS 2 Jazzy types with their type hashes
  and message definitions, one connection per sample topic with the topic's offered QoS
  (:mod:`sideslip_msgs_py.qos`) recorded.
* Each step writes its messages in :data:`topics.SAMPLE_TOPICS` order, all with the
  step's stamp as both header stamp and bag (log) time.
* The run's parameters are a JSON object stored under the key :data:`RUN_METADATA_KEY`
  in rosbag2's ``custom_data``. rosbags writes ``custom_data`` twice: into
  metadata.yaml, and into the .mcap's ``rosbag2`` metadata record (whose
  ``serialized_metadata`` is the same YAML), so a bare .mcap copied out of the
  directory still carries it, and rosbag2 itself keeps it (``BagMetadata.custom_data``).
  No sidecar file is needed.

Reading starts with :func:`open_raw_bag`, shared with the player
(``sideslip_sim.tools.bagsource``): the bag's topics with their offered QoS, and its
serialised messages in log-time order, streamed from disk or, for a damaged .mcap,
the readable part read record by record. :func:`read_bag` then aligns the samples on
the IMU stamp: each IMU message forms one sample with the latest /vehicle/twist and
/vehicle/steering message stamped at or before it (and the latest ground-truth twist,
when the bag has one). Nothing is dropped silently: every IMU message that cannot form
a sample is counted in :attr:`BagContents.notes`.
"""

from __future__ import annotations

import json
import shutil
from collections import Counter
from collections.abc import Callable, Collection, Iterator, Mapping
from contextlib import suppress
from dataclasses import dataclass, field
from operator import attrgetter
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final, NamedTuple

import numpy as np
import numpy.typing as npt

from . import topics
from .cdr import FIELD_COLUMNS, SampleEncoder, decode_columns, stack_rows
from .errors import (
    BagError,
    BagExistsError,
    MissingTopicError,
    NotABagError,
    WrongTopicTypeError,
)
from .messages import (
    ground_truth_fields,
    imu_fields,
    steering_fields,
    twist_fields,
)
from .qos import qos_for
from .sample import SampleArrays, SensorNoiseSigma

if TYPE_CHECKING:
    from rosbags.interfaces import Qos
    from rosbags.rosbag2 import Writer

RUN_METADATA_KEY: Final = "sideslip.run"
"""Key in rosbag2 custom_data whose value is the run's parameters as JSON."""

ROSBAG2_VERSION: Final = 9
"""rosbag2 metadata version written by ROS 2 Jazzy."""

MCAP_MAGIC: Final = b"\x89MCAP0\r\n"


# --- writing ---------------------------------------------------------------------------------


def write_bag(
    path: str | Path,
    arrays: SampleArrays,
    *,
    sigma: SensorNoiseSigma,
    run_metadata: Mapping[str, Any],
    force: bool = False,
    compress: bool = True,
) -> Path:
    """Write samples as a rosbag2 directory at ``path`` and return that path.

    Args:
        path: output directory (its .mcap file is named after it, as rosbag2 does).
        arrays: samples to write; the ground-truth topics are written when they carry truth.
        sigma: sensor noise σ, recorded in the IMU covariances.
        run_metadata: the run's parameters; must be JSON-serialisable (no NaN).
        force: replace an existing bag at ``path`` (see :func:`open_writer`).
        compress: zstd-compress the MCAP chunks (see :func:`open_writer`).

    Raises:
        BagExistsError: ``path`` exists and ``force`` is false, or is not a bag.
        BagError: ``run_metadata`` is not JSON-serialisable, or the bag cannot be created.
    """
    path = Path(path)
    try:
        run_json = json.dumps(dict(run_metadata), sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as err:
        msg = f"{path}: run_metadata is not JSON-serialisable: {err}"
        raise BagError(msg) from None

    encoder = SampleEncoder(sigma)
    rows = encoder.encode(arrays)
    typestore = encoder.factory.typestore
    writer = open_writer(path, force=force, compress=compress)
    writer.set_custom_data(RUN_METADATA_KEY, run_json)
    try:
        streams = []
        for topic in topics.SAMPLE_TOPICS:
            if topic not in rows:
                continue
            conn = writer.add_connection(
                topic,
                topics.TOPIC_TYPES[topic],
                typestore=typestore,
                offered_qos_profiles=[qos_for(topic).to_rosbags()],
            )
            topic_rows = rows[topic]
            streams.append((conn, memoryview(topic_rows.reshape(-1)), topic_rows.shape[1]))
        write = writer.write
        for i, stamp in enumerate(arrays.stamp_ns.tolist()):
            for conn, data, size in streams:
                write(conn, stamp, data[i * size : (i + 1) * size])
        writer.close()
    except BaseException:
        with suppress(Exception):
            writer.abort()
        shutil.rmtree(path, ignore_errors=True)  # we created it: leave no half bag behind
        raise
    return path


def open_writer(path: str | Path, *, force: bool = False, compress: bool = True) -> Writer:
    """Create the bag directory ``path`` and return rosbags' Writer for it, opened.

    Every bag we write is set up alike: rosbag2 metadata version :data:`ROSBAG2_VERSION`,
    storage ``mcap``, and zstd chunk compression unless ``compress`` is false. The .mcap
    file is named after the directory, as rosbag2 does. Add connections, write, then
    ``close()`` (summary and metadata.yaml) or ``abort()``.

    Args:
        path: output directory; must not exist unless ``force``.
        force: replace an existing bag at ``path``. Even then, only a directory that
            looks like a rosbag2 bag (metadata.yaml and/or .mcap files, nothing else) is
            deleted.
        compress: zstd-compress the MCAP chunks (storage-level compression that rosbag2's
            MCAP plugin reads natively; about 4x smaller, about 10 % slower to write).

    Raises:
        BagExistsError: ``path`` exists and ``force`` is false, or it is not a bag.
        BagError: the directory or its .mcap file cannot be created.
    """
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

    path = Path(path)
    _clear_output(path, force=force)
    writer = Writer(path, version=ROSBAG2_VERSION, storage_plugin=StoragePlugin.MCAP)
    if compress:
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    try:
        writer.open()
    except Exception as err:
        if path.is_dir() and not any(path.iterdir()):
            path.rmdir()  # created before the .mcap file failed: leave nothing behind
        msg = f"{path}: cannot create the bag: {err}"
        raise BagError(msg) from None
    return writer


def _clear_output(path: Path, *, force: bool) -> None:
    if not path.exists() and not path.is_symlink():
        return
    if not force:
        msg = f"{path} exists; pass force=True (CLI: --force) to replace it"
        raise BagExistsError(msg)
    if not path.is_dir() or path.is_symlink():
        msg = f"{path} exists and is not a bag directory; refusing to replace it"
        raise BagExistsError(msg)
    strangers = [
        p.name for p in path.iterdir() if not (p.name == "metadata.yaml" or p.suffix == ".mcap")
    ]
    if strangers:
        msg = f"{path} holds files that are not part of a bag ({strangers[:5]}); not replacing it"
        raise BagExistsError(msg)
    shutil.rmtree(path)


# --- reading: raw messages -----------------------------------------------------------------------


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

        Plain tuples: :func:`read_bag` takes these directly, which saves building a
        :class:`RawMessage` per message (about a tenth of its time).
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


def open_raw_bag(path: str | Path) -> RawBag:
    """Open a rosbag2 directory or a bare .mcap file and read its topics.

    The messages are not read here: an intact bag streams them from disk on each
    :meth:`RawBag.messages` pass. An MCAP bag that rosbags cannot open (a recorder killed
    before writing the summary, a copy cut short) is read record by record, in file
    order, up to each file's first damaged record; that readable part is held in memory,
    sorted by log time, with ``truncated`` set and ``notes`` saying where it stopped.

    Raises:
        NotABagError: nothing there, a directory without metadata.yaml, a file that is
            not MCAP, or a bag that neither rosbags nor the record-by-record reader can
            read.
        WrongTopicTypeError: a topic is recorded with two message types.
    """
    path = Path(path)
    if not path.exists():
        msg = f"{path}: no such bag (expected a rosbag2 directory or an .mcap file)"
        raise NotABagError(msg)
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        msg = f"{path}: directory has no metadata.yaml, so it is not a rosbag2 bag"
        raise NotABagError(msg)
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


def _messages_by_topic(path: Path) -> tuple[RawBag, dict[str, list[bytes]]]:
    """The bag and its messages per topic (every topic; log-time order within one).

    A bag whose summary rosbags reads but whose data is damaged further on is read
    again record by record, as one that rosbags cannot open.
    """
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


def _custom_data(raw: RawBag) -> dict[str, str] | None:
    """rosbag2's custom_data: from metadata.yaml, else from the .mcap's metadata record."""
    if raw.path.is_dir():
        yaml_path = raw.path / "metadata.yaml"
        return _custom_data_from_yaml(yaml_path.read_text(encoding="utf-8"), yaml_path)
    if raw.truncated:
        return raw._custom_data
    return _mcap_custom_data(raw.path)


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


# --- reading: decoding and alignment ------------------------------------------------------------


@dataclass(frozen=True)
class _Stream:
    """One topic decoded into columns, sorted by stamp (stable: ties keep bag order)."""

    stamp_ns: npt.NDArray[np.int64]
    columns: dict[str, npt.NDArray[np.float64]]


def _ground_truth_columns(msg: Any) -> dict[str, float]:
    stamp, truth = ground_truth_fields(msg)
    return {
        "stamp_ns": stamp,
        "truth_v_x_mps": truth.v_x_mps,
        "truth_v_y_mps": truth.v_y_mps,
        "truth_yaw_rate_radps": truth.yaw_rate_radps,
    }


# Per-message readers for messages without the fixed layout; keys are SampleArrays columns.
_EXTRACTORS: Final[dict[str, Callable[[Any], Mapping[str, float]]]] = {
    topics.IMU: lambda msg: imu_fields(msg)._asdict(),
    topics.TWIST: lambda msg: twist_fields(msg)._asdict(),
    topics.STEERING: lambda msg: steering_fields(msg)._asdict(),
    topics.GROUND_TRUTH_TWIST: _ground_truth_columns,
}


def _decode(path: Path, topic: str, raws: list[bytes], typestore: Any) -> _Stream:
    pairs = FIELD_COLUMNS[topic]
    rows = stack_rows(raws)
    decoded = decode_columns(topic, rows) if rows is not None else None
    if decoded is not None:
        stamps = decoded["stamp_ns"]
        columns = {column: decoded[field] for field, column in pairs}
    else:  # not our fixed layout (e.g. a real sensor's bag): one message at a time
        msgtype = topics.TOPIC_TYPES[topic]
        extract = _EXTRACTORS[topic]
        try:
            table = [extract(_deserialize(typestore, r, msgtype)) for r in raws]
        except Exception as err:
            msg = f"{path}: cannot decode a {msgtype} message on {topic}: {err}"
            raise BagError(msg) from err
        stamps = np.array([int(row["stamp_ns"]) for row in table], dtype=np.int64)
        columns = {
            column: np.array([row[column] for row in table], dtype=np.float64)
            for _, column in pairs
        }
    order = np.argsort(stamps, kind="stable")
    return _Stream(stamps[order], {k: v[order] for k, v in columns.items()})


def _deserialize(typestore: Any, raw: bytes, msgtype: str) -> Any:
    """``typestore.deserialize_cdr`` that also accepts Fast-CDR's end padding.

    rosbags allows at most 3 bytes after the last field; Fast-CDR (rclpy, ros2 bag
    record) pads a message's end to 8-byte alignment, e.g. JointState to 92 bytes.
    """
    if len(raw) < 4 or bytes(raw[:2]) != b"\x00\x01":  # not little-endian CDR: strict path
        return typestore.deserialize_cdr(raw, msgtype)
    msgdef = typestore.get_msgdef(msgtype)
    message, pos = msgdef.deserialize_cdr_le(raw[4:], 0, msgdef.cls, typestore)
    if len(raw) - 4 - pos >= 8:
        msg = f"{msgtype}: {len(raw) - 4 - pos} bytes after the last field"
        raise ValueError(msg)
    return message


@dataclass(frozen=True)
class BagContents:
    """What :func:`read_bag` found.

    Attributes:
        path: the bag that was read.
        samples: the aligned samples (one per IMU message that could form one).
        run_metadata: the run's parameters (empty when the bag has none).
        topic_counts: messages read per topic (every topic in the bag).
        truncated: the bag was damaged; ``samples`` hold the readable part.
        notes: one line per thing that was not taken verbatim (truncation, IMU messages
            that could not be aligned, samples without ground truth).
    """

    path: Path
    samples: SampleArrays
    run_metadata: dict[str, Any]
    topic_counts: dict[str, int]
    truncated: bool = False
    notes: tuple[str, ...] = ()


def read_bag(path: str | Path) -> BagContents:
    """Read a bag written by :func:`write_bag` or recorded from the contract topics.

    Accepts a rosbag2 directory or a bare .mcap file. A truncated or otherwise damaged
    .mcap yields its readable part, with ``truncated`` set and a note saying where it
    stopped.

    Raises:
        NotABagError: ``path`` is neither a rosbag2 directory nor an MCAP file.
        WrongTopicTypeError: a contract topic has another message type.
        MissingTopicError: a sensor topic is absent or has no message.
        BagError: messages that cannot be decoded, or run metadata that is not JSON.
    """
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    raw, data = _messages_by_topic(path)
    for topic, info in raw.topics.items():
        want = topics.TOPIC_TYPES.get(topic)
        if want is not None and info.msgtype != want:
            msg = f"{path}: topic {topic} has type {info.msgtype!r}; the contract says {want!r}"
            raise WrongTopicTypeError(msg)
    for topic in topics.SENSOR_TOPICS:
        if not data.get(topic):
            found = sorted(t for t, d in data.items() if d)
            msg = f"{path}: no messages on sensor topic {topic} (topics with messages: {found})"
            raise MissingTopicError(msg)

    typestore = get_typestore(Stores.ROS2_JAZZY)
    streams = {
        topic: _decode(path, topic, data[topic], typestore)
        for topic in FIELD_COLUMNS
        if data.get(topic)
    }
    notes = list(raw.notes)
    samples = _align(streams, truncated=raw.truncated, notes=notes)
    return BagContents(
        path=path,
        samples=samples,
        run_metadata=_run_metadata(path, _custom_data(raw)),
        topic_counts={topic: len(d) for topic, d in data.items()},
        truncated=raw.truncated,
        notes=tuple(notes),
    )


def _run_metadata(path: Path, custom: Mapping[str, str] | None) -> dict[str, Any]:
    if not custom or RUN_METADATA_KEY not in custom:
        return {}
    try:
        value = json.loads(custom[RUN_METADATA_KEY])
    except json.JSONDecodeError as err:
        msg = f"{path}: custom_data[{RUN_METADATA_KEY!r}] is not JSON: {err}"
        raise BagError(msg) from None
    if not isinstance(value, dict):
        msg = f"{path}: custom_data[{RUN_METADATA_KEY!r}] is not a JSON object"
        raise BagError(msg)
    return value


def _align(streams: dict[str, _Stream], *, truncated: bool, notes: list[str]) -> SampleArrays:
    """One sample per IMU message, with the latest other messages at or before its stamp."""
    imu = streams[topics.IMU]
    stamps = imu.stamp_ns
    if stamps.size > 1 and (dup := np.flatnonzero(np.diff(stamps) == 0)).size:
        msg = (
            f"{topics.IMU}: {dup.size + 1} or more messages share the stamp "
            f"{int(stamps[dup[0]])} ns; samples need distinct IMU stamps"
        )
        raise BagError(msg)

    keep = np.ones(stamps.shape, dtype=bool)
    partners = [t for t in (topics.TWIST, topics.STEERING) if t in streams]
    for topic in partners:
        first = streams[topic].stamp_ns[0]
        if n_early := int(np.count_nonzero(stamps < first)):
            notes.append(
                f"{n_early} {topics.IMU} message(s) before the first {topic} message "
                "could not be aligned and form no sample"
            )
        keep &= stamps >= first
    if truncated:
        # The partners of the last IMU messages may be in the lost part: a sample past
        # the end of any stream would pair new IMU data with stale data.
        end = min(int(s.stamp_ns[-1]) for s in streams.values())
        if n_late := int(np.count_nonzero(keep & (stamps > end))):
            notes.append(
                f"{n_late} {topics.IMU} message(s) after {end} ns (where the shortest "
                "truncated stream ends) form no sample"
            )
        keep &= stamps <= end

    stamps = stamps[keep]
    columns: dict[str, npt.NDArray[Any]] = {"stamp_ns": stamps}
    columns.update({k: v[keep] for k, v in imu.columns.items()})
    for topic in (*partners, topics.GROUND_TRUTH_TWIST):
        if topic not in streams:
            continue
        stream = streams[topic]
        idx = np.searchsorted(stream.stamp_ns, stamps, side="right") - 1
        missing = idx < 0
        for name, values in stream.columns.items():
            col = values[np.maximum(idx, 0)]
            col[missing] = np.nan
            columns[name] = col
        if topic == topics.GROUND_TRUTH_TWIST and (n_missing := int(missing.sum())):
            notes.append(
                f"{n_missing} sample(s) before the first {topic} message have NaN ground truth"
            )
    return SampleArrays(**columns)
