"""Declare :class:`~sideslip_msgs_py.parameter_spec.ParameterSpec` lists on an rclpy node."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor, ParameterType, ParameterValue
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..parameter_spec import ParameterSpec


class ParameterTypeError(ValueError):
    """A parameter given with another type than the declared one."""


def declare(node: Node, specs: Iterable[ParameterSpec], prefix: str = "") -> dict[str, Any]:
    """Declare each parameter (typed, described, read-only) and return name → value.

    Values keep the spec's Python type. A double also takes an integer (``-p
    real_time_factor:=2``, a YAML ``rate_hz: 400``, a launch argument ``2``): launch
    files and YAML type ``2`` as an integer, and refusing it would stop a node over a
    missing ``.0``. The parameter is then stored as the double 2.0, so ``ros2 param
    get`` shows a double. Any other type change (a string or a bool for a double, a
    double for an integer) is a :class:`ParameterTypeError` (a ValueError naming the
    parameter, the expected type and the value given) at start-up.
    """
    values: dict[str, Any] = {}
    for spec in specs:
        name = f"{prefix}{spec.name}"
        if isinstance(spec.default, float):
            values[spec.name] = _declare_double(node, name, spec)
            continue
        if spec.takes_bool:
            values[spec.name] = _declare_string_or_bool(node, name, spec)
            continue
        descriptor = ParameterDescriptor(description=spec.description, read_only=True)
        try:
            param = node.declare_parameter(name, spec.default, descriptor)
        except InvalidParameterTypeException as err:
            msg = f"parameter {name} must be a {spec.type_name}: {err}"
            raise ParameterTypeError(msg) from None
        values[spec.name] = param.value
    return values


def _declare_double(node: Node, name: str, spec: ParameterSpec) -> float:
    """Declare a double that also takes an integer value; returns the value as a float.

    rclpy refuses an integer override for a statically typed double, so the parameter
    is declared dynamically typed and writable first, its value checked here, and then
    fixed as a read-only double through ``set_descriptor`` (public rclpy API).
    """
    dynamic = ParameterDescriptor(description=spec.description, dynamic_typing=True)
    param = node.declare_parameter(name, spec.default, dynamic)
    if param.type_ not in (Parameter.Type.DOUBLE, Parameter.Type.INTEGER):
        kind = param.type_.name.lower()
        msg = (
            f"parameter {name} must be a double (a number, e.g. 2.0 or 2), "
            f"got {param.value!r} ({kind})"
        )
        raise ParameterTypeError(msg)
    value = float(param.value)
    final = ParameterDescriptor(
        description=spec.description, read_only=True, type=ParameterType.PARAMETER_DOUBLE
    )
    node.set_descriptor(
        name, final, ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
    )
    return value


def _declare_string_or_bool(node: Node, name: str, spec: ParameterSpec) -> str:
    """Declare a string that also takes a bool (:attr:`ParameterSpec.takes_bool`),
    stored as ``true`` / ``false``; fixed as a read-only string as in
    :func:`_declare_double`."""
    dynamic = ParameterDescriptor(description=spec.description, dynamic_typing=True)
    param = node.declare_parameter(name, spec.default, dynamic)
    if param.type_ == Parameter.Type.BOOL:
        value = "true" if param.value else "false"
    elif param.type_ == Parameter.Type.STRING:
        value = str(param.value)
    else:
        kind = param.type_.name.lower()
        msg = f"parameter {name} must be a string or a bool, got {param.value!r} ({kind})"
        raise ParameterTypeError(msg)
    final = ParameterDescriptor(
        description=spec.description, read_only=True, type=ParameterType.PARAMETER_STRING
    )
    node.set_descriptor(
        name, final, ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
    )
    return value
