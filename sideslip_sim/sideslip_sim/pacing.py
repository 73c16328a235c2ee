"""Pacing the sim node's steps in (scaled) real time, and its account of how well it did.

Step stamps come from :class:`~.stream.SampleStream`, whose first sample carries the
wall clock at the moment the first run was ready. :class:`Pacer` schedules that first
step at that wall time, on the monotonic clock (:meth:`Schedule.at_wall_clock`), so at
real time every message leaves at its stamp; step ``k`` is due at
``start + k·dt / real_time_factor`` whatever the earlier steps cost, so lateness never
accumulates into drift. No rclpy here.
"""

from __future__ import annotations

import math
import time
from collections import deque
from typing import Final

import numpy as np

from sideslip_msgs_py.schedule import Schedule, StopSignal, wait_until

LATENESS_KEPT: Final = 240_000
"""Lateness samples kept: the last 10 min at 400 Hz, bounded memory when looping for days."""


class Pacer:
    """Waits for each step's due time and counts the steps published.

    ``real_time_factor`` is simulated seconds per wall second; 0 (or infinity) publishes
    as fast as possible.
    """

    def __init__(self, real_time_factor: float, stop: StopSignal) -> None:
        self._rate = real_time_factor
        self._paced = math.isfinite(real_time_factor) and real_time_factor > 0.0
        self._stop = stop
        self._schedule: Schedule | None = None
        self.steps_published = 0
        self.lateness_ns: deque[int] = deque(maxlen=LATENESS_KEPT)
        """Publish time − due time of recent paced steps [ns]."""

    def wait_for(self, stamp_ns: int) -> bool:
        """Wait until the step stamped ``stamp_ns`` is due; False when a stop was
        requested (then publish nothing more)."""
        if self._stop.is_set():
            return False
        if not self._paced:
            return True
        if self._schedule is None:
            self._schedule = Schedule.at_wall_clock(stamp_ns, self._rate)
        due_ns = self._schedule.deadline_ns(stamp_ns)
        if not wait_until(due_ns, self._stop):
            return False
        self.lateness_ns.append(time.monotonic_ns() - due_ns)
        return True

    def count_published(self) -> None:
        self.steps_published += 1

    def summary(self) -> str:
        """The node's closing log line: steps published and lateness percentiles."""
        late_ms = np.array(self.lateness_ns or [0]) * 1e-6
        p50, p99 = np.percentile(late_ms, 50), np.percentile(late_ms, 99)
        return (
            f"{self.steps_published} steps published; lateness p50/p99/max "
            f"{p50:.3f}/{p99:.3f}/{late_ms.max():.3f} ms"
        )
