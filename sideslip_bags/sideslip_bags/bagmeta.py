"""A rosbag2 bag's metadata.yaml: the document, written atomically, and read back.

Two writers use it. The recorder (:mod:`.bagsink`) rewrites a *provisional*
metadata.yaml at start and at every flush, so that a bag directory whose recorder was
killed is still a rosbag2 directory: its topics and the messages flushed so far, and
in ``custom_data`` the key :data:`IN_PROGRESS_KEY`, which says that the .mcap file has
no summary yet (rosbags refuses such a file; ``sideslip-record --reindex`` finishes
it). A clean stop replaces it with rosbags' own final metadata.yaml, which has no such
key. :mod:`.reindex` writes the final document for a killed bag.

The layout is what rosbags' Writer writes (rosbag2 metadata version 9, one entry per
connection in ``topics_with_message_count``, QoS profiles as v9 names), so that
rosbags and ``ros2 bag`` read either alike.
"""

from __future__ import annotations

import json
import os
import socket
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import yaml

from sideslip_msgs_py.errors import NotABagError

if TYPE_CHECKING:
    from rosbags.interfaces import Qos

METADATA_NAME: Final = "metadata.yaml"

METADATA_VERSION: Final = 9
"""rosbag2 metadata version (ROS 2 Jazzy), as :data:`sideslip_msgs_py.bag.ROSBAG2_VERSION`."""

IN_PROGRESS_KEY: Final = "sideslip.record.in_progress"
"""custom_data key of a provisional metadata.yaml; its value is JSON ``{"pid", "host"}``
naming the recorder that writes the bag."""

NO_MESSAGES_START_NS: Final = 2**63 - 1
"""starting_time of a bag without messages, as rosbags' Writer and rosbag2 write it."""


@dataclass(frozen=True, slots=True)
class TopicEntry:
    """One connection of ``topics_with_message_count``.

    Attributes:
        name: topic name.
        msgtype: ROS 2 type name ('pkg/msg/Name').
        type_hash: RIHS01 type description hash ('RIHS01_...').
        offered_qos: the publishers' offered QoS profiles.
        count: messages on it.
        serialization_format: message encoding ('cdr').
    """

    name: str
    msgtype: str
    type_hash: str
    offered_qos: tuple[Qos, ...]
    count: int
    serialization_format: str = "cdr"


@dataclass(frozen=True, slots=True)
class FileEntry:
    """One storage file of the bag.

    Attributes:
        path: file name relative to the bag directory.
        count: messages in it.
        start_ns: log time [ns] of its first message (ignored when ``count`` is 0).
        end_ns: log time [ns] of its last message (ignored when ``count`` is 0).
    """

    path: str
    count: int
    start_ns: int = 0
    end_ns: int = 0


def metadata_document(
    topics: Sequence[TopicEntry],
    files: Sequence[FileEntry],
    custom_data: Mapping[str, str] | None = None,
) -> dict[str, Any]:
    """The metadata.yaml document of an MCAP bag with storage-level (or no) compression."""
    from rosbags.rosbag2.metadata import dump_qos_v9

    with_messages = [f for f in files if f.count]
    if with_messages:
        start = min(f.start_ns for f in with_messages)
        duration = max(f.end_ns for f in with_messages) - start
    else:
        start, duration = NO_MESSAGES_START_NS, 0
    return {
        "rosbag2_bagfile_information": {
            "version": METADATA_VERSION,
            "storage_identifier": "mcap",
            "relative_file_paths": [f.path for f in files],
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": sum(f.count for f in files),
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": t.name,
                        "type": t.msgtype,
                        "serialization_format": t.serialization_format,
                        "offered_qos_profiles": dump_qos_v9(list(t.offered_qos)),
                        "type_description_hash": t.type_hash,
                    },
                    "message_count": t.count,
                }
                for t in topics
            ],
            # Chunk (storage) compression is inside the MCAP file, as rosbags and
            # rosbag2's MCAP plugin write it: nothing to declare here.
            "compression_format": "",
            "compression_mode": "",
            "files": [
                {
                    "path": f.path,
                    "starting_time": {
                        "nanoseconds_since_epoch": f.start_ns if f.count else NO_MESSAGES_START_NS
                    },
                    "duration": {"nanoseconds": f.end_ns - f.start_ns if f.count else 0},
                    "message_count": f.count,
                }
                for f in files
            ],
            "custom_data": dict(custom_data) if custom_data else None,
            "ros_distro": "rosbags",
        }
    }


def write_metadata(bag_dir: Path, document: Mapping[str, Any]) -> Path:
    """Write ``document`` as ``bag_dir``/metadata.yaml, atomically (temporary file, rename).

    A reader sees the old file or the new one, never half of one, even if the writer is
    killed part way (a ``metadata.yaml.tmp`` may then remain; the next write replaces it).
    """
    path = bag_dir / METADATA_NAME
    tmp = path.with_suffix(".yaml.tmp")
    tmp.write_text(
        yaml.dump(dict(document), Dumper=_Dumper, sort_keys=False, default_flow_style=False),
        encoding="utf-8",
    )
    os.replace(tmp, path)
    return path


_Dumper: Any = getattr(yaml, "CSafeDumper", yaml.SafeDumper)  # libyaml when present: ~10x faster


def read_metadata(bag_dir: Path) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` mapping of ``bag_dir``/metadata.yaml.

    Raises:
        NotABagError: the file is missing, is not YAML, or lacks that mapping.
    """
    path = bag_dir / METADATA_NAME
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as err:
        msg = f"{path}: cannot read rosbag2 metadata: {err}"
        raise NotABagError(msg) from None
    info = doc.get("rosbag2_bagfile_information") if isinstance(doc, dict) else None
    if not isinstance(info, dict):
        msg = f"{path}: no rosbag2_bagfile_information mapping; not rosbag2 metadata"
        raise NotABagError(msg)
    return info


def custom_data_of(info: Mapping[str, Any]) -> dict[str, str]:
    """``custom_data`` of a metadata mapping (empty when it has none)."""
    custom = info.get("custom_data")
    return {str(k): str(v) for k, v in custom.items()} if isinstance(custom, dict) else {}


def in_progress_marker() -> str:
    """The :data:`IN_PROGRESS_KEY` value naming this process."""
    return json.dumps({"pid": os.getpid(), "host": socket.gethostname()})


@dataclass(frozen=True, slots=True)
class RecorderTag:
    """Which recorder wrote a provisional metadata.yaml (from :data:`IN_PROGRESS_KEY`)."""

    pid: int
    host: str

    @classmethod
    def parse(cls, value: str) -> RecorderTag | None:
        try:
            doc = json.loads(value)
            return cls(int(doc["pid"]), str(doc["host"]))
        except (ValueError, TypeError, KeyError):
            return None

    def still_recording(self) -> bool:
        """True if that recorder is still running on this host (as far as can be told).

        A dead pid may have been reused: a live process whose command line (Linux
        /proc) does not mention ``record`` is taken for another program.
        """
        if self.host != socket.gethostname():
            return False  # another machine: cannot tell, assume it stopped
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            pass  # it exists, owned by another user
        try:
            cmdline = Path(f"/proc/{self.pid}/cmdline").read_bytes()
        except OSError:
            return True
        return b"record" in cmdline
