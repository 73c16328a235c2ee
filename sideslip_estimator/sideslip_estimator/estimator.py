"""The estimator core: inputs -> checks -> alignment -> window -> back-end -> estimate.

No rclpy here: the node feeds it decoded message fields and publishes what it
returns, so every rule below is tested without DDS.

Stamp rules (IMU stamps, ns):
* a stamp that goes backwards (a bag replayed in a loop, a restarted sensor) restarts
  the window and the back-end;
* a gap between accepted samples longer than ``max_gap_s`` restarts them too (the
  window must hold one contiguous stretch of driving);
* shorter gaps, longer than 1.5 sample periods, count the missing samples as
  ``dropped`` (lost upstream or by DDS under load) and keep the window.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Final

import numpy as np

from sideslip_msgs_py.features import CHANNELS
from sideslip_msgs_py.messages import NS_PER_S, ImuFields, SteeringFields, TwistFields

from .backends import Backend, Estimate
from .inputs import (
    X_V,
    Aligner,
    InputLimits,
    InputRejected,
    check_imu,
    check_steering,
    check_twist,
)
from .window import SampleWindow

_PERIOD_SAMPLES: Final = 32  # intervals in the running period estimate
_RATE_CHANGE_SAMPLES: Final = 8  # this many long intervals in a row = a new (lower) rate
_MAX_BETA_RAD: Final = math.radians(80.0)


@dataclass(frozen=True)
class EstimatorParams:
    """Runtime rules shared by every back-end (units in the names)."""

    window_steps: int = 100
    max_input_age_s: float = 0.05
    max_gap_s: float = 0.1
    min_speed_mps: float = 1.0
    limits: InputLimits = field(default_factory=InputLimits)

    def __post_init__(self) -> None:
        if self.window_steps < 1:
            raise ValueError(f"window_steps must be >= 1, got {self.window_steps}")
        for name in ("max_input_age_s", "max_gap_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {value!r}")
        if not (math.isfinite(self.min_speed_mps) and self.min_speed_mps >= 0.0):
            raise ValueError(f"min_speed_mps must be finite and >= 0, got {self.min_speed_mps!r}")


@dataclass
class EstimatorStats:
    """Counters since start (the status diagnostic reports them)."""

    accepted: int = 0
    estimates: int = 0
    rejected: Counter[str] = field(default_factory=Counter)
    dropped: int = 0
    resets: Counter[str] = field(default_factory=Counter)
    below_min_speed: int = 0
    no_estimate: int = 0
    """Full window, above min speed, but the back-end had no estimate (e.g. its own
    stricter speed limit)."""
    last_rejection: str = ""


@dataclass(frozen=True)
class Output:
    """One estimate for the IMU sample stamped ``stamp_ns``; ``v_x_mps`` is its X_v."""

    stamp_ns: int
    v_x_mps: float
    estimate: Estimate


class Estimator:
    """Feed it messages in arrival order; ``on_imu`` returns an :class:`Output` or None.

    ``on_*`` raise :class:`InputRejected` (with a short ``reason`` and a message naming
    the topic and field) for input that must not reach the model; the caller logs it.
    The count is kept here either way.
    """

    def __init__(self, backend: Backend, params: EstimatorParams | None = None) -> None:
        self.backend = backend
        self.params = params or EstimatorParams()
        self.window = SampleWindow(self.params.window_steps, len(CHANNELS))
        self.aligner = Aligner(self.params.max_input_age_s)
        self.stats = EstimatorStats()
        self._max_gap_ns = round(self.params.max_gap_s * NS_PER_S)
        self._last_imu_ns: int | None = None
        self._last_accepted_ns: int | None = None
        self._intervals: list[int] = []
        self._long: list[tuple[int, int]] = []  # (interval, drops counted) in a row
        self.period_ns: int | None = None
        """Median IMU period over recent samples (None until measured)."""

    # --- inputs -------------------------------------------------------------------------
    def _reject(self, err: InputRejected) -> InputRejected:
        self.stats.rejected[err.reason] += 1
        self.stats.last_rejection = str(err)
        return err

    def on_twist(self, topic: str, fields: TwistFields) -> None:
        try:
            check_twist(topic, fields, self.params.limits)
        except InputRejected as err:
            raise self._reject(err) from None
        self.aligner.twist = fields

    def on_steering(self, topic: str, fields: SteeringFields) -> None:
        try:
            check_steering(topic, fields, self.params.limits)
        except InputRejected as err:
            raise self._reject(err) from None
        self.aligner.steering = fields

    def reject_message(self, reason: str, detail: str) -> InputRejected:
        """Count a message the node could not decode (e.g. a JointState without the rack)."""
        return self._reject(InputRejected(reason, detail))

    def on_imu(self, topic: str, fields: ImuFields) -> Output | None:
        stamp = fields.stamp_ns
        self._track_stamp(stamp)
        try:
            check_imu(topic, fields, self.params.limits)
            row = self.aligner.sample(fields)
        except InputRejected as err:
            raise self._reject(err) from None
        last = self._last_accepted_ns
        if last is not None and stamp - last > self._max_gap_ns:
            self.restart("gap")
        self.window.push(row, stamp)
        self._last_accepted_ns = stamp
        self.stats.accepted += 1
        try:
            estimate = self.backend.update(self.window.rows(), self.window.stamps_ns())
        except Exception as err:  # a model fault must not take the node down
            self.restart("model_error")
            raise self._reject(
                InputRejected("model_error", f"{self.backend.model_id} failed: {err!r}")
            ) from err
        if not self.window.full:
            return None
        v_x = float(row[X_V])
        if v_x < self.params.min_speed_mps:
            # β = atan2(v_y, v_x) is meaningless at walking pace: no output, not a guess.
            self.stats.below_min_speed += 1
            return None
        if estimate is None:
            self.stats.no_estimate += 1
            return None
        if not (math.isfinite(estimate.beta_rad) and math.isfinite(estimate.variance_rad2)):
            raise self._reject(
                InputRejected("model_non_finite", f"{self.backend.model_id} returned {estimate}")
            )
        if not abs(estimate.beta_rad) < _MAX_BETA_RAD or estimate.variance_rad2 < 0.0:
            # v_y = v_x·tan β is meaningless at ±90°: a model fault, not a car.
            raise self._reject(
                InputRejected("model_out_of_range", f"{self.backend.model_id} returned {estimate}")
            )
        self.stats.estimates += 1
        return Output(stamp, v_x, estimate)

    # --- stamps ---------------------------------------------------------------------------
    def _track_stamp(self, stamp: int) -> None:
        last = self._last_imu_ns
        if last is not None and stamp <= last:
            if stamp == last:
                raise self._reject(InputRejected("duplicate_stamp", f"IMU stamp {stamp} repeated"))
            self._last_imu_ns = stamp
            self.restart("stamp_backwards")
            self.aligner.forget_after(stamp)  # inputs from the old time line
            return
        self._last_imu_ns = stamp
        if last is None:
            return
        interval = stamp - last
        period = self.period_ns
        if period is not None and interval > 1.5 * period:
            if interval > self._max_gap_ns:
                self._long.clear()
                return  # a gap: restarts the window, never enters the period estimate
            drops = round(interval / period) - 1
            self.stats.dropped += drops
            self._long.append((interval, drops))
            if len(self._long) >= _RATE_CHANGE_SAMPLES:
                # Not drops but a slower source (a 100-Hz bag after a 400-Hz run):
                # take the new period and withdraw the drops counted for it.
                self.stats.dropped -= sum(d for _, d in self._long)
                self.period_ns = int(np.median([i for i, _ in self._long]))
                self._long.clear()
                self._intervals.clear()
            return
        self._long.clear()
        self._intervals.append(interval)
        if len(self._intervals) >= _PERIOD_SAMPLES:
            self.period_ns = int(np.median(self._intervals))
            self._intervals.clear()
        elif period is None and len(self._intervals) >= 4:
            self.period_ns = int(np.median(self._intervals))

    def restart(self, why: str) -> None:
        """Empty the window and reset the back-end (counted under ``why``)."""
        self.stats.resets[why] += 1
        self.window.clear()
        self.backend.reset()
        self._last_accepted_ns = None
        if why == "stamp_backwards":
            # Another recording or a restarted source: its rate may differ.
            self.period_ns = None
            self._intervals.clear()
            self._long.clear()

    @property
    def fill(self) -> tuple[int, int]:
        """(rows held, window length)."""
        return len(self.window), self.window.length
