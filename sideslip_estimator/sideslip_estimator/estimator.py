"""The estimator core: inputs -> checks -> alignment -> window -> back-end -> estimate.

No rclpy here: the node feeds it decoded message fields and publishes what it
returns, so every rule below is tested without DDS.

Stamp rules (IMU stamps, ns; :mod:`~sideslip_estimator.stamps` keeps the time line):
* every IMU message is counted once: accepted, rejected (with a reason) or, if it
  never arrived, dropped (a gap of more than 1.5 nominal periods, ``input_rate_hz``,
  counts the missing steps), so published = accepted + rejected + dropped;
* one bad message costs that message, never the window: a repeated stamp is rejected
  (``duplicate_stamp``), a message older than the newest (out of order, at most
  ``max_gap_s`` behind) is skipped (``late_stamp``; a drop it had been counted as is
  withdrawn), one stamped ahead of the line is taken back when the next two messages
  show it (``future_stamps``; the first of them is skipped as late);
* a stamp more than ``max_gap_s`` away either way is held until the next message: if
  that one continues it, a new time line starts there (a pause, a bag played in a
  loop, a restarted sensor: the window and the back-end restart, counted as ``gap`` or
  ``stamp_backwards``); if not, it was one wrong stamp (``bad_stamp``);
* a gap between accepted samples longer than ``max_gap_s`` restarts the window too
  (it must hold one contiguous stretch of driving).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Final

from sideslip_msgs_py.features import CHANNELS
from sideslip_msgs_py.messages import NS_PER_S, ImuFields, SteeringFields, TwistFields
from sideslip_msgs_py.timing import RATE_HZ, WINDOW_STEPS

from .backends import Backend, Estimate
from .imu_scale import ImuScale
from .inputs import (
    X_V,
    Aligner,
    InputLimits,
    InputRejected,
    check_imu,
    check_steering,
    check_twist,
)
from .stamps import StampLine
from .window import SampleWindow

_MAX_BETA_RAD: Final = math.radians(80.0)
CONTRACT_RATE_HZ: Final = RATE_HZ
RATE_TOLERANCE: Final = 0.1
"""A measured IMU rate further than this (relative) from the model's is another rate."""


@dataclass(frozen=True)
class EstimatorParams:
    """Runtime rules shared by every back-end (units in the names)."""

    window_steps: int = WINDOW_STEPS
    max_input_age_s: float = 0.05
    max_gap_s: float = 0.1
    min_speed_mps: float = 1.0
    input_rate_hz: float = 0.0
    """Expected IMU rate [Hz]: steps missing at this rate are counted as dropped.
    0 = the back-end model's rate (:attr:`Backend.sample_period_s`), else 400 Hz."""
    limits: InputLimits = field(default_factory=InputLimits)

    def __post_init__(self) -> None:
        if self.window_steps < 1:
            raise ValueError(f"window_steps must be >= 1, got {self.window_steps}")
        for name in ("max_input_age_s", "max_gap_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {value!r}")
        if not (math.isfinite(self.input_rate_hz) and self.input_rate_hz >= 0.0):
            raise ValueError(f"input_rate_hz must be finite and >= 0, got {self.input_rate_hz!r}")
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
    future_stamps: int = 0
    """Messages found to carry a stamp ahead of the time line (kept, restamped)."""
    wrong_rate: int = 0
    """Samples with a full window but no estimate: the input rate is not the model's."""


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
    The count is kept here either way. ``imu_scale``: the check (and correction) of Y_a
    that every accepted sample passes through before it enters the window.
    """

    def __init__(
        self,
        backend: Backend,
        params: EstimatorParams | None = None,
        imu_scale: ImuScale | None = None,
    ) -> None:
        self.backend = backend
        self.params = params or EstimatorParams()
        self.imu_scale = imu_scale
        self.window = SampleWindow(self.params.window_steps, len(CHANNELS))
        self.aligner = Aligner(self.params.max_input_age_s)
        self.stats = EstimatorStats()
        self._max_gap_ns = round(self.params.max_gap_s * NS_PER_S)
        model_period = getattr(backend, "sample_period_s", None)
        self.model_rate_hz: float | None = None if model_period is None else 1.0 / model_period
        """The rate the back-end's model needs (None: any rate)."""
        self.expected_rate_hz = self.params.input_rate_hz or self.model_rate_hz or CONTRACT_RATE_HZ
        self.line = StampLine(round(NS_PER_S / self.expected_rate_hz), self._max_gap_ns)
        self._last_accepted_ns: int | None = None
        self._held: tuple[str, ImuFields] | None = None  # a jump awaiting the next stamp

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
        self.aligner.add_twist(fields)

    def on_steering(self, topic: str, fields: SteeringFields) -> None:
        try:
            check_steering(topic, fields, self.params.limits)
        except InputRejected as err:
            raise self._reject(err) from None
        self.aligner.add_steering(fields)

    def reject_message(self, reason: str, detail: str) -> InputRejected:
        """Count a message the node could not decode (e.g. a JointState without the rack)."""
        return self._reject(InputRejected(reason, detail))

    def on_imu(self, topic: str, fields: ImuFields) -> Output | None:
        stamp = fields.stamp_ns
        line = self.line
        if self._held is not None:
            held_topic, held = self._held
            self._held = None
            kind = line.classify(stamp)
            if kind != "next" and line.continues(held.stamp_ns, stamp):
                self._new_line(held_topic, held)
            else:
                self._reject(
                    InputRejected(
                        "bad_stamp",
                        f"{held_topic}: stamp {held.stamp_ns} jumped "
                        f"{(held.stamp_ns - (line.last_ns or 0)) / 1e6:+.1f} ms off the time "
                        "line and the next message did not follow it",
                    )
                )
        kind = line.classify(stamp)
        if kind == "first":
            line.start(stamp)
        elif kind == "next":
            line.advance(stamp)
        elif kind == "jump":
            self._held = (topic, fields)
            return None
        elif kind == "duplicate":
            raise self._reject(InputRejected("duplicate_stamp", f"{topic}: stamp {stamp} repeated"))
        elif line.late(stamp) == "late":
            self.stats.dropped = line.dropped
            behind = ((line.last_ns or stamp) - stamp) / 1e6
            raise self._reject(
                InputRejected(
                    "late_stamp",
                    f"{topic}: stamp {stamp} is {behind:.1f} ms behind the newest: "
                    "arrived out of order, skipped",
                )
            )
        else:  # the newest message carried a future stamp: this one continues the line
            self.stats.future_stamps = line.future_stamps
            if self.window.stamps_ns().size and self.window.stamps_ns()[-1] > stamp - 1:
                before = line.last_ns or stamp
                self.window.restamp_newest(before + (stamp - before) // 2)
            line.advance(stamp)
        self.stats.dropped = line.dropped
        return self._sample(topic, fields)

    def _new_line(self, topic: str, held: ImuFields) -> None:
        """Start the time line confirmed at the held message, which enters first."""
        last = self.line.last_ns
        backwards = last is not None and held.stamp_ns < last
        self.restart("stamp_backwards" if backwards else "gap")
        if backwards:
            self.aligner.forget_after(held.stamp_ns)  # inputs from the old time line
        self.line.start(held.stamp_ns)
        try:
            self._sample(topic, held)  # the window just restarted: never an output
        except InputRejected:
            pass  # counted by _sample; the next message goes on

    def _sample(self, topic: str, fields: ImuFields) -> Output | None:
        """Check, align and window one IMU message whose stamp the line took."""
        stamp = fields.stamp_ns
        try:
            check_imu(topic, fields, self.params.limits)
            row = self.aligner.sample(fields)
        except InputRejected as err:
            raise self._reject(err) from None
        last = self._last_accepted_ns
        if last is not None and stamp - last > self._max_gap_ns:
            self.restart("gap")
        if self.imu_scale is not None:
            self.imu_scale.feed(row, stamp)
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
        if self.rate_refused:
            # A window of the wrong duration: the model's answer would be wrong and look
            # right. No estimate until the rate is the model's again.
            self.stats.wrong_rate += 1
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

    @property
    def input_rate_hz(self) -> float | None:
        """Measured IMU rate [Hz] (None until measured); compare ``params.input_rate_hz``."""
        return self.line.rate_hz

    @property
    def rate_refused(self) -> bool:
        """The measured IMU rate is not the back-end model's (no estimates meanwhile)."""
        rate, model = self.line.rate_hz, self.model_rate_hz
        return rate is not None and model is not None and abs(rate / model - 1.0) > RATE_TOLERANCE

    @property
    def held(self) -> int:
        """Messages held (0 or 1): a stamp jump awaiting the next message."""
        return int(self._held is not None)

    def restart(self, why: str) -> None:
        """Empty the window and reset the back-end (counted under ``why``)."""
        self.stats.resets[why] += 1
        self.window.clear()
        self.backend.reset()
        self._last_accepted_ns = None

    @property
    def fill(self) -> tuple[int, int]:
        """(rows held, window length)."""
        return len(self.window), self.window.length
