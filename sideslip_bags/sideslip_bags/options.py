"""Command-line options shared by ``sideslip-record`` and ``sideslip-play`` (no rclpy).

Both tools accept ROS arguments (``--ros-args -r __node:=name -p use_sim_time:=true``)
beside their own; :func:`split_ros_args` separates them the way rcl does, so argparse
only sees ours and ``rclpy.init`` gets the whole command line. The rest checks option
values (remaps, numbers, contract topics), turns a refused one into the one-line error
and exit status :data:`EXIT_BAD_INPUT` (:func:`fail`), and formats the end-of-run counts.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterable, Mapping, Sequence
from typing import Final

from sideslip_msgs_py import topics as contract

from .errors import OptionError

EXIT_BAD_INPUT: Final = 2
"""Exit status for input we refuse (a one-line message on stderr says why)."""

ROS_ARGS: Final = "--ros-args"
ROS_ARGS_END: Final = "--"


def split_ros_args(argv: Sequence[str]) -> tuple[list[str], list[str]]:
    """Split ``argv`` into (our arguments, ROS arguments).

    ROS arguments run from each ``--ros-args`` to the next ``--`` (dropped) or to the
    end, as in rcl. The ROS part keeps its ``--ros-args`` markers.
    """
    ours: list[str] = []
    ros: list[str] = []
    in_ros = False
    for arg in argv:
        if arg == ROS_ARGS:
            in_ros = True
            ros.append(arg)
        elif in_ros and arg == ROS_ARGS_END:
            in_ros = False
        elif in_ros:
            ros.append(arg)
        else:
            ours.append(arg)
    return ours, ros


def parse_remaps(items: Iterable[str]) -> dict[str, str]:
    """``OLD:=NEW`` topic remappings (bag topic → published topic) as a dict.

    Raises:
        OptionError: an item without exactly one ``:=``, an empty or blank side, a name
            with whitespace, or one old topic mapped twice.
    """
    remaps: dict[str, str] = {}
    for item in items:
        parts = item.split(":=")
        if len(parts) != 2 or not all(p and not any(c.isspace() for c in p) for p in parts):
            msg = f"--remap {item!r}: expected OLD:=NEW, e.g. /vehicle/imu:=/car/imu"
            raise OptionError(msg)
        old, new = parts
        if old in remaps and remaps[old] != new:
            msg = f"--remap {item!r}: {old} is already remapped to {remaps[old]}"
            raise OptionError(msg)
        remaps[old] = new
    return remaps


def check_positive(value: float, option: str) -> float:
    """``value`` when it is a finite number > 0, else :class:`OptionError` naming ``option``."""
    if not (math.isfinite(value) and value > 0):
        msg = f"{option} must be a finite number > 0, got {value}"
        raise OptionError(msg)
    return value


def check_non_negative(value: float, option: str) -> float:
    """``value`` when it is a finite number ≥ 0, else :class:`OptionError`."""
    if not (math.isfinite(value) and value >= 0):
        msg = f"{option} must be a finite number >= 0, got {value}"
        raise OptionError(msg)
    return value


def contract_topics(requested: Sequence[str] | None) -> dict[str, str]:
    """Topic → type for ``requested`` contract topics (all of them when None).

    Raises:
        OptionError: a name that is not a contract topic (its type would be unknown).
    """
    if not requested:
        return dict(contract.TOPIC_TYPES)
    chosen: dict[str, str] = {}
    for topic in requested:
        msgtype = contract.TOPIC_TYPES.get(topic)
        if msgtype is None:
            known = ", ".join(sorted(contract.TOPIC_TYPES))
            msg = f"--topics {topic}: not a contract topic, so its type is unknown (known: {known})"
            raise OptionError(msg)
        chosen[topic] = msgtype
    return chosen


def fail(prog: str, err: BaseException) -> int:
    """Print ``prog: error: <err>`` as one line on stderr; return :data:`EXIT_BAD_INPUT`."""
    text = " ".join(str(err).split()) or type(err).__name__
    print(f"{prog}: error: {text}", file=sys.stderr)
    return EXIT_BAD_INPUT


def format_counts(counts: Mapping[str, int]) -> str:
    """``/a 3, /b 0`` in topic order, for the end-of-run log line."""
    return ", ".join(f"{topic} {n}" for topic, n in sorted(counts.items())) or "no topics"
