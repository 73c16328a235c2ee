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

Reading starts in :mod:`.bag_raw` (:func:`open_raw_bag`, re-exported here and shared
with the player, ``sideslip_bags.bagsource``): the bag's topics with their offered
QoS, and its serialised messages in log-time order. :func:`read_bag` then aligns the
samples on the IMU stamp: each IMU message forms one sample with the latest
/vehicle/twist and /vehicle/steering message stamped at or before it (and the latest
ground-truth twist, when the bag has one). Nothing is dropped silently: every IMU
message that cannot form a sample is counted in :attr:`BagContents.notes`.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Mapping
from contextlib import suppress
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import numpy as np
import numpy.typing as npt

from . import topics
from .bag_raw import (
    MCAP_MAGIC,
    RawBag,
    RawMessage,
    RawTopic,
    open_raw_bag,
    read_messages_by_topic,
)
from .cdr import FIELD_COLUMNS, SampleEncoder, decode_columns, stack_rows
from .errors import (
    BagError,
    BagExistsError,
    MissingTopicError,
    WrongTopicTypeError,
)
from .message_fields import channel_values, stamp_ns
from .qos import qos_for
from .sample import SampleArrays, SensorNoiseSigma

if TYPE_CHECKING:
    from rosbags.rosbag2 import Writer

RUN_METADATA_KEY: Final = "sideslip.run"
"""Key in rosbag2 custom_data whose value is the run's parameters as JSON."""

ROSBAG2_VERSION: Final = 9
"""rosbag2 metadata version written by ROS 2 Jazzy."""


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


# --- reading: decoding and alignment ------------------------------------------------------------


@dataclass(frozen=True)
class _Stream:
    """One topic decoded into columns, sorted by stamp (stable: ties keep bag order)."""

    stamp_ns: npt.NDArray[np.int64]
    columns: dict[str, npt.NDArray[np.float64]]


def _decode(path: Path, topic: str, raws: list[bytes], typestore: Any) -> _Stream:
    pairs = FIELD_COLUMNS[topic]
    rows = stack_rows(raws)
    decoded = decode_columns(topic, rows) if rows is not None else None
    if decoded is not None:
        stamps = decoded["stamp_ns"]
        columns = {column: decoded[field] for field, column in pairs}
    else:  # not our fixed layout (e.g. a real sensor's bag): one message at a time
        msgtype = topics.TOPIC_TYPES[topic]
        stamp_list, table = [], []
        try:
            for raw in raws:
                msg = _deserialize(typestore, raw, msgtype)
                stamp_list.append(stamp_ns(msg))
                table.append(channel_values(msg, topic))
        except Exception as err:
            msg = f"{path}: cannot decode a {msgtype} message on {topic}: {err}"
            raise BagError(msg) from err
        stamps = np.array(stamp_list, dtype=np.int64)
        values = np.array(table, dtype=np.float64).reshape(len(table), len(pairs))
        columns = {column: values[:, i].copy() for i, (_, column) in enumerate(pairs)}
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
    raw, data = read_messages_by_topic(path)
    for topic, info in raw.topics.items():
        want = topics.TOPIC_TYPES.get(topic)
        if want is not None and info.msgtype != want:
            msg = f"{path}: topic {topic} has type {info.msgtype!r}; the contract says {want!r}"
            raise WrongTopicTypeError(msg)
    for topic in topics.SENSOR_TOPICS:
        if not data.get(topic):
            found = sorted(t for t, d in data.items() if d)
            msg = (
                f"{path}: no messages on sensor topic {topic} (topics with messages: {found}; "
                "recorded with other topics? read it through a topic map, --topic-map)"
            )
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
        run_metadata=_run_metadata(path, raw.custom_data()),
        topic_counts={topic: len(d) for topic, d in data.items()},
        truncated=raw.truncated,
        notes=tuple(notes),
    )


def read_run_metadata(path: str | Path) -> dict[str, Any]:
    """The run metadata of the bag at ``path`` ({} when it has none), without reading
    its messages. Raises as :func:`open_raw_bag` and :class:`BagError` for metadata that
    is not a JSON object."""
    path = Path(path)
    return _run_metadata(path, open_raw_bag(path).custom_data())


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
    partners = [t for t in topics.SENSOR_TOPICS if t != topics.IMU and t in streams]
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


__all__ = [
    "MCAP_MAGIC",
    "ROSBAG2_VERSION",
    "RUN_METADATA_KEY",
    "BagContents",
    "RawBag",
    "RawMessage",
    "RawTopic",
    "open_raw_bag",
    "open_writer",
    "read_bag",
    "read_run_metadata",
    "write_bag",
]
