"""Message types the tools handle: the Python class to publish, the definition to record.

A type is named as ROS 2 names it (``sensor_msgs/msg/Imu``). The player and the
recorder need its Python message class (:func:`message_class`: rclpy creates publishers
and raw subscriptions with it); the recorder also needs its definition and RIHS01 hash
from rosbags' ROS 2 Jazzy typestore (:func:`jazzy_typestore`, :func:`check_recordable`)
to write the bag. A type that lacks either is an :class:`~.errors.UnknownTypeError`.
"""

from __future__ import annotations

import importlib
from typing import Any

from .errors import UnknownTypeError


def message_class(type_name: str) -> type:
    """The Python message class of a ROS 2 type name: 'sensor_msgs/msg/Imu' → Imu.

    Raises:
        UnknownTypeError: a malformed name, or no installed package defines the type.
    """
    parts = type_name.split("/")
    if len(parts) != 3 or not all(p.isidentifier() for p in parts):
        msg = f"message type {type_name!r} is not of the form 'pkg/msg/Name'"
        raise UnknownTypeError(msg)
    package, kind, name = parts
    try:
        cls = getattr(importlib.import_module(f"{package}.{kind}"), name)
    except (ImportError, AttributeError):
        msg = f"message type {type_name!r}: no Python package defines it (is {package} installed?)"
        raise UnknownTypeError(msg) from None
    return cls


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
