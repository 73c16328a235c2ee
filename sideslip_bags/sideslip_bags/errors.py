"""Exceptions of the record/play tools; each CLI prints one as one line and exits 2.

Bag problems (missing, not a bag, existing output) are the
:mod:`sideslip_msgs_py.errors` bag exceptions; these classes cover the rest.
"""

from __future__ import annotations


class ToolError(Exception):
    """Base class: bad input to ``sideslip-record`` or ``sideslip-play``."""


class OptionError(ToolError, ValueError):
    """An option value that cannot be used (rate, remap syntax, topic name); names it."""


class UnknownTypeError(ToolError):
    """A message type that has no Python message class or no rosbags definition."""
