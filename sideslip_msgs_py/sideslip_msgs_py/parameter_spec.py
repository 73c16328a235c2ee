"""ROS parameter declarations as plain data, so nodes, back-ends and ``--help`` share them."""

from __future__ import annotations

import textwrap
from collections.abc import Iterable
from dataclasses import dataclass


@dataclass(frozen=True)
class ParameterSpec:
    """One ROS parameter: name, default (its type fixes the parameter type), description."""

    name: str
    default: bool | int | float | str
    description: str
    takes_bool: bool = False
    """A string parameter that also takes a bool (``:=true``, YAML ``true``), stored as
    the string ``true`` / ``false``: a setting with more answers than on and off that
    once was a bool."""

    @property
    def type_name(self) -> str:
        return {bool: "bool", int: "int", float: "double", str: "string"}[type(self.default)]


def help_text(title: str, groups: Iterable[tuple[str, Iterable[ParameterSpec]]]) -> str:
    """A ``--help`` page listing every parameter with type, default and description."""
    lines = [title, ""]
    for heading, specs in groups:
        lines.append(f"{heading}:")
        for p in specs:
            lines.append(f"  {p.name} ({p.type_name}, default {p.default!r})")
            lines.extend(
                textwrap.wrap(p.description, 88, initial_indent=" " * 6, subsequent_indent=" " * 6)
            )
        lines.append("")
    lines.append("Set parameters with --ros-args -p name:=value or --params-file FILE.yaml;")
    lines.append("remap topics with --ros-args -r /old:=/new.")
    return "\n".join(lines)
