"""Playback timing: when each bag message is due, and what bag time it is now.

Playback runs on an absolute schedule: message ``i`` is due at
``start + (t_i − t_first) / rate`` on the monotonic clock, however long publishing the
earlier messages took. Sleeping a fixed ``dt`` after each publish would add the work's
time to every interval and drift; a late message is instead published at once and the
next deadline is unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Schedule:
    """Maps bag (log) time to monotonic wall time for one pass through a bag.

    Attributes:
        start_ns: monotonic time [ns] at which the first message is due.
        t_first_ns: bag log time [ns] of the first message.
        rate: playback speed factor (2 = twice as fast as recorded); > 0.
    """

    start_ns: int
    t_first_ns: int
    rate: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate) and self.rate > 0):
            msg = f"rate must be a finite number > 0, got {self.rate}"
            raise ValueError(msg)

    def deadline_ns(self, t_ns: int) -> int:
        """Monotonic time [ns] at which the message logged at ``t_ns`` is due."""
        return self.start_ns + round((t_ns - self.t_first_ns) / self.rate)

    def bag_time_ns(self, now_ns: int) -> int:
        """Bag time [ns] that corresponds to monotonic time ``now_ns`` (for /clock).

        Before the start this is the first message's time; it never runs backwards
        within one pass.
        """
        return self.t_first_ns + max(0, round((now_ns - self.start_ns) * self.rate))
