"""Field paths into ROS messages: ``twist.linear.x``, ``position[0]``, ``position[steering_rack]``.

One syntax for the contract's channel registry (:mod:`.channels`) and for topic maps
(:mod:`.topic_map`): dotted attribute names; an index selects an array element by
position (``position[0]``) or a ``sensor_msgs/JointState`` joint by name
(``position[steering_rack]``: the element at that name's index in ``msg.name``).
Works on rclpy messages and rosbags dataclasses alike (attribute access only).
"""

from __future__ import annotations

import operator
import re
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import Any

_INDEX = re.compile(r"^(\w+)\[([^\]]+)\]$")


class FieldPathError(KeyError):
    """A message lacks the element a path names (a joint, an array entry)."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


@dataclass(frozen=True, slots=True)
class PathPart:
    """One step of a path: attribute ``name``, then element ``index`` when given."""

    name: str
    index: int | str | None = None


@cache
def parse(path: str) -> tuple[PathPart, ...]:
    """The steps of ``path`` (an integer index by position, any other by joint name)."""
    parts = []
    for part in path.split("."):
        m = _INDEX.match(part)
        if m is None:
            parts.append(PathPart(part))
            continue
        index = m.group(2)
        parts.append(PathPart(m.group(1), int(index) if index.lstrip("-").isdigit() else index))
    return tuple(parts)


def joint_of(path: str) -> str | None:
    """The JointState joint a path names (``position[steering_rack]`` → ``steering_rack``)."""
    last = parse(path)[-1]
    return last.index if isinstance(last.index, str) else None


def _element(msg: Any, container: Any, part: PathPart) -> Any:
    if isinstance(part.index, int):
        return container[part.index]
    names = list(msg.name)
    if part.index not in names:
        raise FieldPathError(f"JointState.name has no {part.index!r} (names: {names})")
    i = names.index(part.index)
    if len(container) <= i:
        raise FieldPathError(f"JointState.{part.name} has no entry for {part.index!r}")
    return container[i]


@cache
def getter(path: str) -> Callable[[Any], Any]:
    """A function reading ``path`` from a message (compiled once per path: the node reads
    every field of every 400-Hz message through it)."""
    parts = parse(path)
    if all(p.index is None for p in parts):
        return operator.attrgetter(path)

    def get(msg: Any) -> Any:
        value = msg
        for part in parts:
            value = getattr(value, part.name)
            if part.index is not None:
                value = _element(msg, value, part)
        return value

    return get


def field_value(msg: Any, path: str) -> Any:
    """The value at ``path`` of ``msg``.

    Raises:
        AttributeError: no such field; FieldPathError (a KeyError): no such joint or
        entry; IndexError: an index past the array's end.
    """
    return getter(path)(msg)


def set_field(msg: Any, path: str, value: float) -> None:
    """Write ``value`` (as float) at ``path`` of ``msg``, whose arrays already have room."""
    parts = parse(path)
    target = msg
    for part in parts[:-1]:
        target = getattr(target, part.name)
        if part.index is not None:
            target = _element(msg, target, part)
    last = parts[-1]
    if last.index is None:
        setattr(target, last.name, float(value))
        return
    container = getattr(target, last.name)
    i = last.index if isinstance(last.index, int) else list(msg.name).index(last.index)
    container[i] = float(value)
