"""Inputs from another stack's topics: the node's topic map, checked against the back-end.

A topic map (docs/topic-maps.md) names each input topic and its message type; the node
subscribes to those topics with the classes loaded here and hands each message to the
:class:`~sideslip_msgs_py.live_inputs.LiveMapper`, which forms the samples.
"""

from __future__ import annotations

import importlib
from typing import Any

from sideslip_msgs_py.live_inputs import LiveMapper
from sideslip_msgs_py.topic_map import TopicMap, TopicMapError

from .backends import Backend

MappedInputs = tuple[LiveMapper, dict[str, tuple[Any, str]]]
"""The topic map's mapper, and per topic its message class and type name."""


def mapped_inputs(path: str, backend: Backend) -> MappedInputs | None:
    """The topic map's mapper and message class per topic (None without a map).

    Raises ValueError naming the file: a map that cannot be read or used live, a type
    that is not installed, or a model channel the map leaves out."""
    if not path:
        return None
    try:
        topic_map = TopicMap.load(path)
        types = topic_map.input_types()
    except TopicMapError as err:
        raise ValueError(f"topic_map_file: {err}") from None
    reads = set(getattr(backend, "channels", ()))
    missing = sorted(reads - set(topic_map.channels) - {"y_v_mps"})
    if "y_v_mps" in reads and "y_v_mps" not in topic_map.channels:
        missing.append("y_v_mps")
    if missing:
        raise ValueError(
            f"topic_map_file: {path} does not map {missing}, which {backend.model_id} reads"
        )
    classes = {}
    for topic, name in types.items():
        package, _, type_name = name.partition("/msg/")
        cls = None
        # An empty or dotted package would make import_module a relative import (a
        # TypeError), and a name that is no class (a module, a dunder) no message type.
        if package.isidentifier() and type_name.isidentifier() and not type_name.startswith("_"):
            try:
                cls = getattr(importlib.import_module(f"{package}.msg"), type_name)
            except (ImportError, AttributeError, ValueError):
                cls = None
        if not isinstance(cls, type):
            raise ValueError(f"topic_map_file: message type {name} of {topic} is not installed")
        classes[topic] = (cls, name)
    return LiveMapper(topic_map), classes
