"""Declare :class:`~sideslip_msgs_py.parameters.ParameterSpec` lists on an rclpy node."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from ..parameters import ParameterSpec


def declare(node: Node, specs: Iterable[ParameterSpec], prefix: str = "") -> dict[str, Any]:
    """Declare each parameter (typed, described, read-only) and return name → value.

    Values keep the spec's Python type: an int given for a double parameter is
    accepted by rclpy only as a double, so a YAML ``rate_hz: 400`` is a clear error at
    start-up rather than a silent type change (rclpy raises InvalidParameterTypeException).
    """
    values: dict[str, Any] = {}
    for spec in specs:
        name = f"{prefix}{spec.name}"
        descriptor = ParameterDescriptor(description=spec.description, read_only=True)
        param = node.declare_parameter(name, spec.default, descriptor)
        values[spec.name] = param.value
    return values
