"""What the command-line tools share: the error a user can fix and its exit code."""

from __future__ import annotations

from typing import Final

EXIT_BAD_INPUT: Final = 2


class CliError(Exception):
    """Bad input a user can fix: printed as one line, exit code 2."""
