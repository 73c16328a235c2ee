"""The IMU time line: which stamps continue it, which are late, duplicated or a jump.

Pure bookkeeping for :class:`~sideslip_estimator.estimator.Estimator` (stamps in ns),
so that every IMU message the publisher sent is counted exactly once: received
(accepted or rejected by the estimator) or missing (``dropped``), and one bad message
costs that message, never the window:

* ``next``: newer than the newest stamp by at most ``max_gap``. Intervals longer than
  1.5 nominal periods count the missing steps as dropped (the nominal period is the
  model's step; the rate is never re-learnt from the gaps, so drops under load are
  never taken back as "a slower source": a slower source shows as a measured rate
  below the nominal one instead, see :attr:`StampLine.rate_hz`).
* ``duplicate``: a stamp received before (within the last :data:`RECENT` messages).
* ``late``: older than the newest by at most ``max_gap`` and not seen before: a message
  that arrived out of order. It cannot enter the window any more (the window has moved
  on), so it is skipped; if it falls in an interval whose steps were counted as
  dropped, one of them moves from dropped to this late message (it did arrive).
* ``jump``: more than ``max_gap`` away either way: a new time line (a pause, a bag
  played in a loop, a restarted sensor) or one message with a wrong stamp. Only the
  next message tells which, so the caller holds it (:meth:`StampLine.continues`).

A stamp more than 1.5 periods ahead (one that counted drops) is a *suspect*: when the
next message falls between the previous stamp and it, that one is late (two neighbours
swapped in transit); when a second does too, the suspect carried a wrong (future)
stamp: :meth:`StampLine.late` takes the line back to the first of them and withdraws
the drops the suspect had counted (its own message arrived, only its stamp was wrong).
A future stamp so costs the one message behind it, never the window.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Final, Literal

import numpy as np

RECENT: Final = 64
"""Stamps remembered for duplicate detection (160 ms at 400 Hz; beyond ``max_gap`` a
stamp is a jump anyway)."""
_RATE_INTERVALS: Final = 32

Kind = Literal["first", "next", "late", "duplicate", "jump"]


@dataclass
class _Suspect:
    """The newest message jumped ahead over ``gap`` from ``before_ns``."""

    before_ns: int
    gap: _Gap
    behind_ns: int | None = None  # the first later message stamped behind it


@dataclass
class _Gap:
    """An interval (start, end) whose ``missing`` steps are counted as dropped."""

    start_ns: int
    end_ns: int
    missing: int


class StampLine:
    """Classifies IMU stamps against the current time line and counts missing steps."""

    def __init__(self, period_ns: int, max_gap_ns: int) -> None:
        if period_ns <= 0 or max_gap_ns <= 0:
            msg = f"period and max gap must be > 0 ns, got {period_ns}, {max_gap_ns}"
            raise ValueError(msg)
        self.period_ns = period_ns
        self.max_gap_ns = max_gap_ns
        self.last_ns: int | None = None
        """Newest stamp of the line (None before the first message)."""
        self.dropped = 0
        """Steps missing from the line, net of late arrivals that filled them."""
        self.future_stamps = 0
        """Messages found to carry a stamp ahead of the line (taken back)."""
        self._recent: deque[int] = deque(maxlen=RECENT)
        self._gaps: deque[_Gap] = deque()
        self._suspect: _Suspect | None = None
        self._intervals: deque[int] = deque(maxlen=_RATE_INTERVALS)
        self._since_rate = 0
        self._rate_hz: float | None = None

    # --- classification ------------------------------------------------------------------
    def classify(self, stamp_ns: int) -> Kind:
        last = self.last_ns
        if last is None:
            return "first"
        if last < stamp_ns <= last + self.max_gap_ns:
            return "next"
        if last - self.max_gap_ns <= stamp_ns <= last:
            return "duplicate" if stamp_ns in self._recent else "late"
        return "jump"

    def continues(self, held_ns: int, stamp_ns: int) -> bool:
        """Whether ``stamp_ns`` follows a held jump ``held_ns`` closely enough to confirm
        it as the start of a new time line."""
        return held_ns < stamp_ns <= held_ns + self.max_gap_ns

    # --- updates -------------------------------------------------------------------------
    def start(self, stamp_ns: int) -> None:
        """Begin a new time line at ``stamp_ns`` (first message or a confirmed jump)."""
        self.last_ns = stamp_ns
        self._recent.clear()
        self._recent.append(stamp_ns)
        self._gaps.clear()
        self._suspect = None
        self._intervals.clear()  # another source or recording may have another rate
        self._rate_hz = None
        self._since_rate = 0

    def advance(self, stamp_ns: int) -> int:
        """Take a ``next`` stamp; returns the steps counted as dropped before it."""
        last = self.last_ns
        assert last is not None and stamp_ns > last
        interval = stamp_ns - last
        steps = round(interval / self.period_ns)
        missing = steps - 1 if interval > 1.5 * self.period_ns else 0
        self._suspect = None
        if missing:
            self.dropped += missing
            gap = _Gap(last, stamp_ns, missing)
            self._gaps.append(gap)
            self._suspect = _Suspect(last, gap)
        self._intervals.append(interval)
        self._since_rate += 1
        if len(self._intervals) >= 4 and (self._rate_hz is None or self._since_rate >= 8):
            # The median every 8 messages: the rate is read on every sample.
            self._rate_hz = 1e9 / float(np.median(self._intervals))
            self._since_rate = 0
        self._accept(stamp_ns)
        return missing

    def late(self, stamp_ns: int) -> Literal["late", "future_before"]:
        """Take a ``late`` stamp. ``late``: skip the message; a drop it fills is
        withdrawn. ``future_before``: the newest message carried a stamp ahead of the
        line; the line is taken back to the message before this one, and the caller
        treats this one as ``next``."""
        suspect = self._suspect
        if suspect is not None and suspect.before_ns < stamp_ns:
            if suspect.behind_ns is not None and suspect.behind_ns < stamp_ns:
                self.dropped -= suspect.gap.missing
                if suspect.gap in self._gaps:
                    self._gaps.remove(suspect.gap)
                self.future_stamps += 1
                self.last_ns = suspect.behind_ns
                self._suspect = None
                return "future_before"
            suspect.behind_ns = stamp_ns
        for gap in reversed(self._gaps):
            if gap.start_ns < stamp_ns < gap.end_ns and gap.missing:
                gap.missing -= 1
                self.dropped -= 1
                break
        self._recent.append(stamp_ns)
        return "late"

    def _accept(self, stamp_ns: int) -> None:
        self.last_ns = stamp_ns
        self._recent.append(stamp_ns)
        horizon = stamp_ns - self.max_gap_ns
        while self._gaps and self._gaps[0].end_ns < horizon:
            self._gaps.popleft()  # nothing that late is "late" any more

    @property
    def rate_hz(self) -> float | None:
        """Measured message rate [Hz]: 1 / the median of the last intervals (robust to
        a few drops; a slower source shows here). None until measured."""
        return self._rate_hz
