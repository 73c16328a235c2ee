"""Publishing on an absolute schedule: when each message is due, and waiting for it.

Message ``i`` is due at ``start + (t_i − t_first) / rate`` on the monotonic clock,
however long publishing the earlier messages took. Sleeping a fixed ``dt`` after each
publish would add the work's time to every interval and drift; a late message is
instead published at once and the next deadline is unchanged. The bag player
(``t_i``: log times) and the sim node (``t_i``: sample stamps, ``rate``: its real-time
factor) both pace through :class:`Schedule` and :func:`wait_until`. No rclpy here.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Final, Protocol

SPIN_S: Final = 0.0002
"""Wake this long [s] before a deadline and spin the rest: ``sleep()`` overshoots."""

WATCH_S: Final = 0.005
"""Waits longer than this [s] watch the stop signal, and end this long before the
deadline (``Event.wait`` is less punctual than ``sleep``)."""


class StopSignal(Protocol):
    """What :func:`wait_until` watches: a ``threading.Event`` or a node's stop flag."""

    def is_set(self) -> bool: ...

    def wait(self, timeout: float, /) -> bool: ...


@dataclass(frozen=True, slots=True)
class Schedule:
    """Maps log (or stamp) time to monotonic wall time for one pass through the messages.

    Attributes:
        start_ns: monotonic time [ns] at which the first message is due.
        t_first_ns: log time [ns] of the first message.
        rate: speed factor (2 = twice as fast as recorded); > 0.
    """

    start_ns: int
    t_first_ns: int
    rate: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate) and self.rate > 0):
            msg = f"rate must be a finite number > 0, got {self.rate}"
            raise ValueError(msg)

    @classmethod
    def at_wall_clock(cls, t_first_ns: int, rate: float = 1.0) -> Schedule:
        """A schedule whose first message is due when the wall clock (``time.time_ns``)
        reads ``t_first_ns``, kept on the monotonic clock: at ``rate`` 1 every message
        stamped with wall time leaves at its stamp."""
        return cls(t_first_ns + time.monotonic_ns() - time.time_ns(), t_first_ns, rate)

    def deadline_ns(self, t_ns: int) -> int:
        """Monotonic time [ns] at which the message logged at ``t_ns`` is due."""
        return self.start_ns + round((t_ns - self.t_first_ns) / self.rate)

    def bag_time_ns(self, now_ns: int) -> int:
        """Log time [ns] that corresponds to monotonic time ``now_ns`` (for /clock).

        Before the start this is the first message's time; it never runs backwards
        within one pass.
        """
        return self.t_first_ns + max(0, round((now_ns - self.start_ns) * self.rate))


def wait_until(deadline_ns: int, stop: StopSignal) -> bool:
    """Wait until monotonic time ``deadline_ns``; False when a stop was requested.

    Never returns True before the deadline. Sleeps most of the way, then spins the last
    :data:`SPIN_S`, so a message leaves within microseconds of its deadline. A wait
    longer than :data:`WATCH_S` (a pause between runs, a slow rate) watches ``stop``
    and returns False as soon as it is set; shorter ones check it at the end.
    """
    wait_s = (deadline_ns - time.monotonic_ns()) * 1e-9 - SPIN_S
    if wait_s > WATCH_S:
        if stop.wait(wait_s - WATCH_S):
            return False
        wait_s = (deadline_ns - time.monotonic_ns()) * 1e-9 - SPIN_S
    if wait_s > 0.0:
        # clock_nanosleep on the monotonic clock: wakes within tens of µs.
        time.sleep(wait_s)
    while time.monotonic_ns() < deadline_ns:
        pass
    return not stop.is_set()
