"""Exception classes of sideslip_msgs_py.

Every message names the file, topic or field at fault and what was expected, so a CLI
can print ``str(err)`` as its one line.
"""

from __future__ import annotations


class ContractError(Exception):
    """Base class: something does not match the sideslip wire contract."""


class UnknownTopicError(ContractError, KeyError):
    """A topic name that is not part of the wire contract."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class SampleArraysError(ContractError, ValueError):
    """Columnar sample arrays are inconsistent (lengths, dtypes, stamp order)."""


class MessageFieldError(ContractError, ValueError):
    """A message field does not hold what the contract says (e.g. joint name, array size)."""


class BagError(ContractError):
    """Base class for bag reading and writing errors; messages name the path."""


class BagExistsError(BagError, FileExistsError):
    """The output bag exists and ``force`` was not given (or it is not a bag to replace)."""


class NotABagError(BagError):
    """The path is neither a rosbag2 directory nor an MCAP file we can read."""


class MissingTopicError(BagError):
    """A required contract topic has no messages in the bag."""


class WrongTopicTypeError(BagError):
    """A contract topic in the bag carries a different message type."""
