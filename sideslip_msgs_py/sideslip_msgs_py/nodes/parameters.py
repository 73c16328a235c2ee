"""Declare :class:`~sideslip_msgs_py.parameters.ParameterSpec` lists on an rclpy node."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.node import Node

from ..parameters import ParameterSpec


class ParameterTypeError(ValueError):
    """A parameter given with another type than the declared one."""


def declare(node: Node, specs: Iterable[ParameterSpec], prefix: str = "") -> dict[str, Any]:
    """Declare each parameter (typed, described, read-only) and return name → value.

    Values keep the spec's Python type: rclpy refuses an int given for a double, so a
    YAML ``rate_hz: 400`` is a :class:`ParameterTypeError` (a ValueError naming the
    parameter) at start-up rather than a silent type change.
    """
    values: dict[str, Any] = {}
    for spec in specs:
        name = f"{prefix}{spec.name}"
        descriptor = ParameterDescriptor(description=spec.description, read_only=True)
        try:
            param = node.declare_parameter(name, spec.default, descriptor)
        except InvalidParameterTypeException as err:
            msg = f"parameter {name} must be a {spec.type_name} (e.g. 400.0, not 400): {err}"
            raise ParameterTypeError(msg) from None
        values[spec.name] = param.value
    return values
