"""Y_a's scale and bias from a car's own drives, without any reference.

Every model and the UKF read Y_a as the CG's lateral acceleration a_y in the horizontal
frame. A body-fixed IMU without an attitude reads gravity through the body's roll (9–13 %
more than a_y on passenger cars), and a MEMS accelerometer's scale is good to about
1 %; the UKF-anchored models lose 2–4× for a 1 % error (docs/evaluation/imu-mounting).
With a reference velocity :mod:`.accelerometer_check` measures the scale; this module
measures it from what every car records: speed and yaw rate.

The kinematics of a rigid body in plane motion, a_y = v̇_y + v_x·ψ̇, integrated over
time, give

    ∫ Y_a dt = s·∫ v_x ψ̇ dt + b·t + s·v_y(t) + c

for Y_a = s·a_y + b (s = 1 + κ the scale, b a bias [m/s²]). The integrals grow with
every corner (∫ v_x ψ̇ dt is the heading change times the speed), while v_y stays
bounded (|β| of a few degrees), so s is their ratio up to the lateral velocity. That
is a nuisance correlated with the cornering, which biased the plain ratio by up to 2 %
low on our validation cars; it is taken out by regressing on what v_y follows in the
tyres' linear range, the low-passed Y_a and ψ̇ (a single-track car's v_y is a linear
combination of a_y and ψ̇ in a steady turn), with every column low-passed alike
(:data:`FIT_CUTOFF_HZ`). Each stretch of driving (a run split into chunks of
:data:`CHUNK_S`) has its own constant c. The roll's lag behind a_y does not matter: the
integral takes in all the gravity a corner puts into Y_a, however late. Driving that
cannot separate s from v_y (too little cornering, or a slalom at one frequency whose
heading change is a sinusoid like v_y) gives no estimate.

On the 8 validation cars (18 drives each, paper noise) the scale came out 0.9991–1.0011
for a level IMU and the body-frame IMU's κ within 0.0035 of the true one; how the
estimators do with it: docs/evaluation/imu-mounting.

The spread is a jackknife over the chunks: the 1-σ of s that the drives' own scatter
implies (it does not include a bias of the method).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import numpy.typing as npt

CHUNK_S: Final = 60.0
"""About how long [s] a chunk with one constant c (and one jackknife group) is: a
stretch is cut into equal chunks of 2/3 to 4/3 of this."""
MAX_GAP_STEPS: Final = 5.0
"""A step over this many times the run's median step is a gap: the stretch ends."""
MIN_ROWS: Final = 30
"""Stretches and chunks with fewer rows are left out."""
MIN_SPEED_MPS: Final = 5.0
"""Rows slower than this [m/s] are not fitted (they are still integrated)."""
MIN_LATERAL_MPS2: Final = 1.0
MIN_CORNERING_S: Final = 20.0
"""Less cornering than this [s] at |v_x·ψ̇| > :data:`MIN_LATERAL_MPS2` [m/s²] gives no
estimate."""
MIN_CHUNKS: Final = 3
"""Fewer chunks than this give no spread (a jackknife of one or two is meaningless)."""
SCALE_TOLERANCE: Final = 0.03
"""|s − 1| beyond this is reported (as :data:`.accelerometer_check.SCALE_TOLERANCE`)."""
CUTOFF_HZ: Final = 2.0
"""Low-pass [Hz] that tells cornering from noise (:data:`MIN_LATERAL_MPS2`)."""
FIT_CUTOFF_HZ: Final = 0.5
"""Low-pass [Hz] of the fitted columns. Chosen on the validation cars: without it a
sine sweep's drives alone (0.2–2 Hz) came out 5–8 % low; at 0.5 Hz within 1 %, and the
cars' whole drives within 0.11 % for a level IMU (0.25 Hz: 0.19 %)."""
MIN_SEPARATION: Final = 0.02
"""Below this separation the drives cannot tell the scale from the lateral velocity
(a slalom at one frequency: its heading change is itself a sinusoid), and no estimate
is given."""

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class AccelerometerScale:
    """Y_a = scale·a_y + bias_mps2, as the drives imply (module docstring).

    scale: s = 1 + κ [-]; spread: its jackknife 1-σ over chunks [-] (NaN with fewer
    than :data:`MIN_CHUNKS`); bias_mps2: b [m/s²] (0 unless fitted); chunks, samples:
    what the fit used; cornering_s: time at |v_x·ψ̇| > :data:`MIN_LATERAL_MPS2` [s];
    separation: 1 − R² of ∫ v_x ψ̇ dt on the other columns (the lateral-velocity terms
    and, with a bias, time) [-]; near 0 when the driving cannot tell the scale from
    them (module docstring).
    """

    scale: float
    spread: float
    bias_mps2: float
    chunks: int
    samples: int
    cornering_s: float
    separation: float

    @property
    def channel_fix(self) -> tuple[float, float]:
        """(scale, offset) that turn the recorded Y_a into a_y: a_y = Y_a·scale + offset
        (a topic map's ``y_a_mps2`` takes them on top of its own)."""
        return 1.0 / self.scale, -self.bias_mps2 / self.scale

    @property
    def warning(self) -> str | None:
        """One line when Y_a is off by more than :data:`SCALE_TOLERANCE`, else None."""
        if abs(self.scale - 1.0) <= SCALE_TOLERANCE:
            return None
        fix, _ = self.channel_fix
        return (
            f"warning: Y_a is {self.scale:.3f} × the lateral acceleration the yaw rate and "
            f"speed imply (± {self.spread:.3f}, {self.cornering_s:.0f} s of cornering): a "
            "body-frame IMU without attitude, or a scale error? Scale y_a_mps2 by "
            f"{fix:.4f} (sideslip-imu-scale writes the topic map)"
        )


@functools.lru_cache(maxsize=16)
def _low_pass(cutoff_hz: float, rate_hz: float) -> FloatArray:
    """Second-order Butterworth sections (designed once per rate: an online estimate
    fits a chunk a minute at the same rate)."""
    from scipy.signal import butter

    return butter(2, cutoff_hz, fs=rate_hz, output="sos")


def _smooth(x: FloatArray, rate_hz: float, cutoff_hz: float = CUTOFF_HZ) -> FloatArray:
    """``x`` (along its first axis) through a second-order zero-phase low-pass."""
    from scipy.signal import sosfiltfilt

    # The rate to 1e-6 Hz: the same design for a rate measured with float jitter.
    return sosfiltfilt(_low_pass(cutoff_hz, round(rate_hz, 6)), x, axis=0)


def _cumulative(y: FloatArray, t: FloatArray) -> FloatArray:
    """∫ y dt from t[0] (trapezoids)."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))])


def _stretches(runs: Sequence[Any]) -> list[tuple[FloatArray, FloatArray, FloatArray, FloatArray]]:
    """(t [s], v_x, ψ̇, Y_a) of every finite, strictly increasing stretch of the runs
    without a gap (a step over :data:`MAX_GAP_STEPS` times the run's median step): the
    integrals and filters must not run across a hole."""
    out = []
    for run in runs:
        s = run.samples
        if len(s.stamp_ns) < MIN_ROWS:
            continue
        t = (np.asarray(s.stamp_ns) - s.stamp_ns[0]) * 1e-9
        cols = [np.asarray(c, dtype=float) for c in (s.x_v_mps, s.yaw_rate_radps, s.y_a_mps2)]
        ok = np.isfinite(cols[0]) & np.isfinite(cols[1]) & np.isfinite(cols[2])
        step = np.diff(t)
        positive = step[step > 0.0]
        if positive.size == 0:
            continue
        # A row after a gap (or a repeated / backward stamp) starts a new stretch.
        gap = (step <= 0.0) | (step > MAX_GAP_STEPS * np.median(positive))
        # Stretches: runs of finite rows, cut before every row after a gap.
        label = np.cumsum(np.concatenate([[True], gap]) | ~ok)
        for k in np.unique(label[ok]):
            rows = np.flatnonzero(ok & (label == k))
            if rows.size >= MIN_ROWS:
                out.append((t[rows], *(c[rows] for c in cols)))
    return out


@dataclass(frozen=True)
class ChunkSums:
    """One chunk's share of the fit: its centred normal equations XᵀX, Xᵀy (columns
    ∫ v_x ψ̇ dt, low-passed Y_a, low-passed ψ̇ and, with a bias, t; all low-passed alike),
    the rows fitted and its cornering [s]. Chunks add up (the fit is their sum), so a
    chunk is also the unit that an online estimate keeps, forgets and stores."""

    xtx: FloatArray
    xty: FloatArray
    samples: int
    cornering_s: float


def stretch_chunks(
    t: FloatArray,
    u: FloatArray,
    r: FloatArray,
    f_y: FloatArray,
    chunk: npt.NDArray[np.int64],
    *,
    fit_bias: bool,
) -> list[ChunkSums]:
    """The :class:`ChunkSums` of one stretch: time t [s] (strictly increasing, no gap),
    X_v [m/s], ψ̇ [rad/s], Y_a [m/s²], finite; ``chunk`` numbers each row's chunk (< 0:
    filtered and integrated, not fitted). Empty at a rate too low for the filters."""
    return chunk_sums(
        StretchColumns(t, _cumulative(f_y, t), _cumulative(u * r, t), f_y, r, u, u * r),
        chunk,
        fit_bias=fit_bias,
    )


@dataclass(frozen=True)
class StretchColumns:
    """What the fit reads of a stretch, row by row: t [s], ∫ Y_a dt [m/s], ∫ v_x ψ̇ dt
    [m/s], Y_a [m/s²], ψ̇ [rad/s], v_x [m/s] and v_x ψ̇ [m/s²]. Any linear filter applied
    to every column alike keeps the identity the fit rests on (the online estimate
    block-averages them)."""

    t: FloatArray
    i_y: FloatArray
    i_ur: FloatArray
    f_y: FloatArray
    r: FloatArray
    u: FloatArray
    ur: FloatArray


def chunk_sums(
    cols: StretchColumns, chunk: npt.NDArray[np.int64], *, fit_bias: bool
) -> list[ChunkSums]:
    """:func:`stretch_chunks` from the stretch's columns (``chunk`` < 0: the margins an
    online estimate keeps so that the filters settle, filtered and not fitted)."""
    t = cols.t
    rate = 1.0 / float(np.median(np.diff(t)))
    if rate <= 2.5 * CUTOFF_HZ:
        return []
    # Every column through the same zero-phase low-pass: the identity holds for the
    # filtered signals too, and it keeps the corners while it takes out the fast
    # steering whose lateral velocity lags a_y and ψ̇ (beyond the nuisance terms).
    i_y, i_ur, f_s, r_s, t_s = _smooth(
        np.stack([cols.i_y, cols.i_ur, cols.f_y, cols.r, t - t[0]], axis=1), rate, FIT_CUTOFF_HZ
    ).T
    moving = cols.u > MIN_SPEED_MPS
    dt = np.concatenate([np.diff(t), [0.0]])
    # Cornering by speed and yaw rate, not by Y_a: what is measured must not decide
    # whether it is measured.
    turning = np.abs(_smooth(cols.ur, rate)) > MIN_LATERAL_MPS2
    out = []
    for k in np.unique(chunk[moving & (chunk >= 0)]):
        rows = moving & (chunk == k)
        if rows.sum() < MIN_ROWS:
            continue
        x_cols = [i_ur[rows], f_s[rows], r_s[rows]]
        if fit_bias:
            x_cols.append(t_s[rows])  # the bias's ∫ b dt, filtered alike
        x = np.stack(x_cols, axis=1)
        y = i_y[rows]
        x = x - x.mean(axis=0)  # the chunk's own constant c
        y = y - y.mean()
        cornering = float(dt[rows & turning].sum())
        out.append(ChunkSums(x.T @ x, x.T @ y, int(rows.sum()), cornering))
    return out


def equal_chunks(t: FloatArray) -> npt.NDArray[np.int64]:
    """Each row's chunk when a stretch is cut into equal chunks of about :data:`CHUNK_S`
    (none a short leftover: each is a jackknife group and should weigh like the others)."""
    duration = t[-1] - t[0]
    n_chunks = max(1, round(duration / CHUNK_S))
    return np.minimum(np.floor((t - t[0]) / (duration / n_chunks)), n_chunks - 1).astype(np.int64)


def solve(chunks: Sequence[ChunkSums], *, fit_bias: bool) -> AccelerometerScale | None:
    """Scale (and bias) from the chunks' sums; None with too little cornering or driving
    that cannot separate the scale from the lateral velocity."""
    cornering_s = float(sum(c.cornering_s for c in chunks))
    if not chunks or cornering_s < MIN_CORNERING_S:
        return None
    xtx = sum(c.xtx for c in chunks)
    xty = sum(c.xty for c in chunks)
    try:
        coef = np.linalg.solve(xtx, xty)  # (an exactly singular system: no estimate)
        # 1 − R² of ∫ v_x ψ̇ dt on the nuisance columns: how much of the heading change
        # the lateral-velocity terms cannot explain (1/VIF of the scale).
        nuisance = xtx[1:, 1:]
        explained = xtx[0, 1:] @ np.linalg.solve(nuisance, xtx[1:, 0])
        separation = float(1.0 - explained / xtx[0, 0])
    except np.linalg.LinAlgError:
        return None
    if not separation >= MIN_SEPARATION:
        return None
    spread = math.nan
    if len(chunks) >= MIN_CHUNKS:
        # Leave one chunk out at a time, from the sums (no refit of the rows).
        loo = np.array([_scale_without(xtx - c.xtx, xty - c.xty) for c in chunks])
        n = len(chunks)
        spread = float(math.sqrt((n - 1) / n * np.sum((loo - loo.mean()) ** 2)))
    bias = float(coef[3]) if fit_bias else 0.0
    samples = sum(c.samples for c in chunks)
    return AccelerometerScale(
        float(coef[0]), spread, bias, len(chunks), samples, cornering_s, separation
    )


def _scale_without(xtx: FloatArray, xty: FloatArray) -> float:
    """The scale from the sums less one chunk (least squares where they are singular)."""
    try:
        return float(np.linalg.solve(xtx, xty)[0])
    except np.linalg.LinAlgError:
        return float(np.linalg.lstsq(xtx, xty, rcond=None)[0][0])


def estimate_scale(runs: Sequence[Any], *, fit_bias: bool = False) -> AccelerometerScale | None:
    """Y_a's scale (and with ``fit_bias`` its bias) from ``runs`` (records with
    ``samples``: ``sideslip_training.dataset.Run``); None with too little cornering at
    speed. No reference is read."""
    chunks = [
        c
        for t, u, r, f_y in _stretches(runs)
        for c in stretch_chunks(t, u, r, f_y, equal_chunks(t), fit_bias=fit_bias)
    ]
    return solve(chunks, fit_bias=fit_bias)
