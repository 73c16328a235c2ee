"""Fixed-length sliding window of input rows with O(1) push and a contiguous view."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt


class SampleWindow:
    """The last ``length`` rows (oldest first) of ``width`` channels, plus their stamps.

    Every row is written twice, at ``i`` and ``i + length`` of a buffer twice as long,
    so the newest ``length`` rows are always one contiguous slice: a model reads the
    window without a copy or a roll at 400 Hz.
    """

    def __init__(self, length: int, width: int) -> None:
        if length < 1 or width < 1:
            msg = f"window length and width must be >= 1, got {length} x {width}"
            raise ValueError(msg)
        self.length = length
        self.width = width
        self._rows = np.zeros((2 * length, width))
        self._stamps = np.zeros(2 * length, dtype=np.int64)
        self._next = 0
        self._count = 0

    def __len__(self) -> int:
        """Rows held (0 .. length)."""
        return self._count

    @property
    def full(self) -> bool:
        return self._count == self.length

    def push(self, row: npt.ArrayLike, stamp_ns: int) -> None:
        """Append one row (``width`` values); the oldest falls out when full."""
        i, n = self._next, self.length
        self._rows[i] = row
        self._rows[i + n] = self._rows[i]
        self._stamps[i] = self._stamps[i + n] = stamp_ns
        self._next = (i + 1) % n
        self._count = min(self._count + 1, n)

    def rows(self) -> npt.NDArray[np.float64]:
        """The held rows, oldest first, shape (len, width): a read-only view."""
        end = self._next + self.length
        view = self._rows[end - self._count : end]
        view.flags.writeable = False
        return view

    def stamps_ns(self) -> npt.NDArray[np.int64]:
        """Stamps [ns] of the held rows, oldest first (a read-only view)."""
        end = self._next + self.length
        view = self._stamps[end - self._count : end]
        view.flags.writeable = False
        return view

    def restamp_newest(self, stamp_ns: int) -> None:
        """Correct the newest row's stamp (a message found to carry a wrong one)."""
        if not self._count:
            raise IndexError("restamp_newest on an empty window")
        i = (self._next - 1) % self.length
        self._stamps[i] = self._stamps[i + self.length] = stamp_ns

    def clear(self) -> None:
        self._next = 0
        self._count = 0
