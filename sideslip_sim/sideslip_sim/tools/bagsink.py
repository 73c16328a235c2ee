"""Write received messages into a rosbag2 MCAP bag as they arrive (the recorder's output).

The bag is what ``ros2 bag record -s mcap`` writes, set up by
:func:`sideslip_msgs_py.bag.open_writer` as every bag we write (metadata version
:data:`~sideslip_msgs_py.bag.ROSBAG2_VERSION`, storage ``mcap``, by default zstd chunk
compression): serialisation ``cdr``, Jazzy message definitions and type hashes, each
topic's offered QoS profiles. Messages are stored byte for byte as received.

rosbags' MCAP writer collects messages in an in-memory chunk of up to 1 MiB;
:meth:`BagSink.flush` writes the pending chunk to disk so that, should the recorder be
killed without a chance to close the bag, the .mcap file still holds everything up to
the last flush (readable with :func:`sideslip_msgs_py.bag.read_bag` on the file).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sideslip_msgs_py.bag import open_writer
from sideslip_msgs_py.errors import BagError

from .errors import UnknownTypeError
from .offers import OfferedQos


def jazzy_typestore() -> Any:
    """rosbags' ROS 2 Jazzy typestore (message definitions and RIHS01 type hashes)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def check_recordable(msgtype: str, typestore: Any) -> None:
    """Raise :class:`UnknownTypeError` unless the typestore can describe ``msgtype``."""
    try:
        typestore.generate_msgdef(msgtype, ros_version=2)
    except Exception:
        msg = f"message type {msgtype!r} is not in the ROS 2 Jazzy typestore; cannot record it"
        raise UnknownTypeError(msg) from None


class BagSink:
    """An open output bag. Not thread-safe: use it from one thread.

    Create it with :func:`open_sink`; :meth:`close` writes the summary and
    metadata.yaml (it is idempotent).
    """

    def __init__(self, writer: Any, typestore: Any) -> None:
        self._writer = writer
        self._typestore = typestore
        self._connections: dict[str, Any] = {}
        self._counts: dict[str, int] = {}
        self._closed = False

    @property
    def path(self) -> Path:
        return Path(self._writer.path)

    @property
    def counts(self) -> dict[str, int]:
        """Messages written per topic (every added topic, 0 when none arrived)."""
        return dict(self._counts)

    def add_topic(self, topic: str, msgtype: str, offers: Sequence[OfferedQos]) -> None:
        """Declare ``topic`` with its publishers' offered QoS; before its first message."""
        if topic in self._connections:
            msg = f"{self.path}: topic {topic} is already in the bag"
            raise BagError(msg)
        self._connections[topic] = self._writer.add_connection(
            topic,
            msgtype,
            typestore=self._typestore,
            offered_qos_profiles=[o.to_rosbags() for o in offers],
        )
        self._counts[topic] = 0

    def write(self, topic: str, log_time_ns: int, data: bytes | memoryview) -> None:
        """Append one serialised message, logged at ``log_time_ns`` [ns]."""
        self._writer.write(self._connections[topic], log_time_ns, data)
        self._counts[topic] += 1

    def flush(self) -> None:
        """Write the pending chunk (if it holds messages) to the file and flush it."""
        if self._closed:
            return
        storage = self._writer.storage
        chunk = getattr(storage, "chunk", None)
        # rosbags internals (McapWriter, pinned in constraints.txt): skip when they differ.
        if chunk is not None and getattr(chunk, "msgs", None) and hasattr(storage, "close_chunk"):
            storage.close_chunk()
            storage.bio.flush()

    def close(self) -> None:
        """Finish the bag: last chunk, MCAP summary, metadata.yaml. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._writer.close()


def open_sink(path: str | Path, *, compress: bool = True, force: bool = False) -> BagSink:
    """Create the output bag directory ``path`` (its .mcap is named after it).

    Args:
        path: output directory; must not exist unless ``force``.
        compress: zstd-compress MCAP chunks (storage compression, read natively by
            rosbag2's MCAP plugin).
        force: replace an existing bag at ``path`` (only a directory that holds nothing
            but metadata.yaml and .mcap files is deleted).

    Raises:
        BagExistsError: ``path`` exists and ``force`` is false, or it is not a bag.
        BagError: the directory cannot be created.
    """
    return BagSink(open_writer(path, force=force, compress=compress), jazzy_typestore())
