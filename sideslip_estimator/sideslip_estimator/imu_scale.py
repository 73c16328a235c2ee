"""The estimator's own check of Y_a while it drives, and (``apply``) its correction.

Every model and the UKF read Y_a as the lateral acceleration in the horizontal frame. A
body-fixed IMU without an attitude reads 9–15 % more (the roll's share of gravity), a
roll error in the attitude or the mounting adds a bias, and every estimator that reads
Y_a loses 2–14× for it (docs/evaluation/imu-mounting). :class:`ImuScale` measures Y_a's
scale and bias from the speed and yaw rate of the samples the node accepts
(:mod:`.online_accelerometer_scale`), reports them in /sideslip/status and, in mode
``apply``, corrects Y_a once the estimate is confident (its jackknife spread within
``max_spread`` over at least three chunks). The measurement is kept in ``state_file``
across restarts, so a car that has driven a few minutes once starts corrected.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Final

import numpy as np
import numpy.typing as npt

from .accelerometer_scale import MIN_CORNERING_S, AccelerometerScale
from .inputs import X_V, Y_A, YAW_RATE
from .online_accelerometer_scale import OnlineAccelerometerScale, StateError

MODES: Final = ("off", "report", "apply")


@dataclass(frozen=True)
class ImuScaleParams:
    """How the node checks Y_a (``imu_scale.*`` parameters; units in the names)."""

    mode: str = "apply"
    """off: no check; report: measure and report (WARN beyond ±3 %); apply: also correct
    Y_a with the measured scale and bias once the estimate is confident."""
    state_file: str = ""
    """Where the measurement is kept across restarts ("" = not kept)."""
    max_spread: float = 0.005
    """The scale's 1-σ (jackknife over chunks) under which the estimate is applied [-]."""
    memory_chunks: int = 30
    """Chunks (about a minute of driving each) the estimate remembers."""

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"imu_scale.mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        if not (math.isfinite(self.max_spread) and self.max_spread > 0.0):
            raise ValueError(f"imu_scale.max_spread must be finite and > 0, got {self.max_spread}")
        if self.memory_chunks < 10:
            raise ValueError(f"imu_scale.memory_chunks must be >= 10, got {self.memory_chunks}")


class ImuScale:
    """Feed it every accepted model row (:meth:`feed`); it measures Y_a and, in mode
    ``apply``, corrects the row's Y_a in place. ``max_gap_s``: a longer step between
    rows ends a stretch of driving (the estimator core's own ``max_gap_s``)."""

    def __init__(self, params: ImuScaleParams, max_gap_s: float) -> None:
        self.params = params
        self.online = OnlineAccelerometerScale(
            fit_bias=True, memory_chunks=params.memory_chunks, max_gap_s=max_gap_s
        )
        self._saved_at = 0  # online.completed when the state was last saved
        self._remounts_reported = 0

    @property
    def confident(self) -> AccelerometerScale | None:
        """The estimate, when it is good enough to apply; else None."""
        est = self.online.estimate
        if est is None or not est.spread <= self.params.max_spread:  # NaN: too few chunks
            return None
        return est

    @property
    def applied(self) -> tuple[float, float] | None:
        """(scale, offset) applied to Y_a now (None: Y_a is passed on as recorded)."""
        est = self.confident
        if self.params.mode != "apply" or est is None:
            return None
        return est.channel_fix

    def feed(self, row: npt.NDArray[np.float64], stamp_ns: int) -> None:
        """Measure with ``row`` as recorded, then correct its Y_a (mode ``apply``)."""
        self.online.add(stamp_ns, float(row[X_V]), float(row[YAW_RATE]), float(row[Y_A]))
        fix = self.applied
        if fix is not None:
            row[Y_A] = row[Y_A] * fix[0] + fix[1]

    # --- state ------------------------------------------------------------------------
    def load(self) -> str | None:
        """Restore the measurement from ``state_file``; returns a line to log (None: no
        file configured). An unreadable file is reported and the measurement starts
        afresh: a calibration cache must not keep the estimator from running."""
        path = self.params.state_file
        if not path:
            return None
        if not Path(path).exists():
            return f"imu_scale: no state in {path} yet, measuring from scratch"
        try:
            self.online.restore(json.loads(Path(path).read_text(encoding="utf-8")))
        except (OSError, ValueError, StateError) as err:
            return f"imu_scale: state file {path} unreadable ({err}), measuring from scratch"
        self._remounts_reported = self.online.remounts
        return f"imu_scale: {len(self.online.chunks)} chunk(s) restored from {path}; {self.line()}"

    def save(self, *, final: bool = False) -> str | None:
        """Write the state to ``state_file`` when a chunk was added since the last save
        (``final``: close the open stretch first, at shutdown). Returns an error line or
        None. The file is replaced atomically: a crash leaves the old or the new one."""
        path = self.params.state_file
        if final:
            self.online.end_stretch()
        if not path or self.online.completed == self._saved_at:
            return None
        tmp = f"{path}.tmp"
        try:
            Path(tmp).write_text(json.dumps(self.online.state()), encoding="utf-8")
            os.replace(tmp, path)
        except OSError as err:
            return f"imu_scale: cannot write state file {path}: {err}"
        self._saved_at = self.online.completed
        return None

    # --- status -----------------------------------------------------------------------
    def line(self) -> str:
        """One line on where the measurement stands."""
        est = self.online.estimate
        if est is None:
            cornering = sum(c.cornering_s for c in self.online.chunks)
            return (
                f"Y_a scale: measuring ({cornering:.0f} of {MIN_CORNERING_S:.0f} s of "
                f"cornering, {len(self.online.chunks)} chunk(s))"
            )
        state = "applied" if self.applied is not None else "not applied"
        if self.confident is None:
            state += f", spread over {self.params.max_spread:g}"
        return (
            f"Y_a scale {est.scale:.4f} ± {est.spread:.4f}, bias {est.bias_mps2:+.3f} m/s² "
            f"({state}; {est.chunks} chunks, {est.cornering_s:.0f} s of cornering)"
        )

    def report(self) -> tuple[list[str], dict[str, str]]:
        """The status's warnings (a remount since the last report; a confident scale
        beyond ±3 % that is not applied) and its values."""
        warnings = []
        online, est = self.online, self.confident
        if online.remounts > self._remounts_reported:
            self._remounts_reported = online.remounts
            warnings.append(
                "Y_a's scale changed (IMU remounted?): the older measurement was forgotten"
            )
        if est is not None and self.params.mode != "apply" and est.warning:
            fix = est.channel_fix[0]
            warnings.append(
                f"Y_a is {est.scale:.3f} × what speed and yaw rate imply (body-frame IMU "
                f"without attitude, or a scale error?): imu_scale.mode apply, or scale "
                f"y_a_mps2 by {fix:.4f} in the topic map"
            )
        measured = online.estimate  # confident or not
        shown = ("n/a",) * 3
        if measured is not None:
            shown = tuple(f"{v:.4f}" for v in (measured.scale, measured.spread, measured.bias_mps2))
        values = {
            "imu_scale_mode": self.params.mode,
            **dict(
                zip(("imu_scale", "imu_scale_spread", "imu_scale_bias_mps2"), shown, strict=True)
            ),
            "imu_scale_applied": "yes" if self.applied is not None else "no",
            "imu_scale_chunks": str(len(online.chunks)),
            "imu_scale_cornering_s": f"{sum(c.cornering_s for c in online.chunks):.1f}",
            "imu_scale_remounts": str(online.remounts),
            "imu_scale_state": self.line(),
        }
        return warnings, values
