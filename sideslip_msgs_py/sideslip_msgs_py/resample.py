"""Recorded samples at a model's step: resampled from another rate, or refused.

A network sees windows of ``window_steps`` rows ``step_s`` apart. Fed a bag at another
rate, its window spans another duration and every derivative another scale, and it is
scored silently wrong (an IMU at 200 Hz gave 6× the error with exit 0). So every bag a
model trains on or is scored on is brought to the model's step first:

* within :data:`RATE_TOLERANCE` of the step: used as it is;
* faster (downsampling): each column is low-pass filtered (Butterworth, order 4,
  zero phase, cut-off at :data:`CUTOFF_OF_NYQUIST` of the new Nyquist frequency) so
  that nothing above the new Nyquist frequency folds back, then interpolated onto the
  new grid;
* slower (upsampling): interpolated linearly (no new content to remove);
* outside :data:`MIN_RATE_HZ`–:data:`MAX_RATE_HZ`: refused (:class:`RateError` names
  both rates).

Interpolation runs inside each contiguous stretch (gaps longer than ``max_gap_s`` or
three source steps are kept as gaps), on a grid starting at the stretch's first stamp.
A sample whose source neighbours hold NaN stays NaN (it is reported and excluded, as in
a bag at the model's rate). Offline only: the zero-phase filter looks ahead.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from typing import Final

import numpy as np
import numpy.typing as npt

from .sample import SampleArrays

MIN_RATE_HZ: Final = 50.0
MAX_RATE_HZ: Final = 1000.0
RATE_TOLERANCE: Final = 0.01
"""Relative difference of the measured step from the model's below which a bag is
used as it is (clock drift and jitter, not another rate)."""
CUTOFF_OF_NYQUIST: Final = 0.8
_FILTER_ORDER: Final = 4
_MIN_FILTERED: Final = 30  # shorter stretches cannot be filtered forward and back


class RateError(ValueError):
    """Samples at a rate that cannot be brought to the model's step."""


@dataclass(frozen=True)
class Resampled:
    """``samples`` at the model's step; ``source_rate_hz`` is what the bag had;
    ``note`` says what was done (None: used as it was)."""

    samples: SampleArrays
    source_rate_hz: float | None
    note: str | None = None


def measured_step_s(stamp_ns: npt.NDArray[np.int64]) -> float | None:
    """Median interval between consecutive stamps [s] (None with fewer than 2)."""
    if stamp_ns.size < 2:
        return None
    return float(np.median(np.diff(stamp_ns))) * 1e-9


def to_step(samples: SampleArrays, step_s: float, *, max_gap_s: float = 0.1) -> Resampled:
    """``samples`` brought to ``step_s`` (see the module docstring).

    Raises:
        RateError: the measured rate is outside 50–1000 Hz (the message names it and
            the model's rate).
    """
    if not (np.isfinite(step_s) and step_s > 0.0):
        raise ValueError(f"step_s must be a positive number of seconds, got {step_s!r}")
    source = measured_step_s(samples.stamp_ns)
    if source is None or source <= 0.0:
        return Resampled(samples, None)
    rate, target_rate = 1.0 / source, 1.0 / step_s
    if abs(source / step_s - 1.0) <= RATE_TOLERANCE:
        return Resampled(samples, rate)
    if not MIN_RATE_HZ <= rate <= MAX_RATE_HZ:
        msg = (
            f"samples at {rate:.1f} Hz: outside the {MIN_RATE_HZ:g}-{MAX_RATE_HZ:g} Hz that "
            f"can be resampled to the model's {target_rate:g} Hz"
        )
        raise RateError(msg)
    downsample = source < step_s
    columns = _float_columns(samples)
    stamps = samples.stamp_ns
    gap_ns = max(max_gap_s, 3.0 * source) * 1e9
    bounds = [0, *(np.flatnonzero(np.diff(stamps) > gap_ns) + 1).tolist(), stamps.size]
    step_ns = round(step_s * 1e9)
    out_stamps: list[npt.NDArray[np.int64]] = []
    out_cols: dict[str, list[npt.NDArray[np.float64]]] = {k: [] for k in columns}
    dropped = 0
    for start, stop in itertools.pairwise(bounds):
        t = stamps[start:stop]
        if downsample and t.size < _MIN_FILTERED:
            dropped += t.size
            continue
        grid = np.arange(int(t[0]), int(t[-1]) + 1, step_ns, dtype=np.int64)
        x = (t - t[0]).astype(np.float64)
        xq = (grid - t[0]).astype(np.float64)
        out_stamps.append(grid)
        for name, col in columns.items():
            y = col[start:stop]
            out_cols[name].append(_resample_column(x, y, xq, source, step_s, downsample))
    if not out_stamps:
        empty = {k: np.empty(0) for k in columns}
        return Resampled(
            dataclasses.replace(samples, stamp_ns=np.empty(0, dtype=np.int64), **empty),
            rate,
            f"resampling {rate:.1f} Hz to {target_rate:g} Hz left no stretch long enough",
        )
    new = dataclasses.replace(
        samples,
        stamp_ns=np.concatenate(out_stamps),
        **{k: np.concatenate(v) for k, v in out_cols.items()},
    )
    how = (
        f"low-pass {CUTOFF_OF_NYQUIST * target_rate / 2:g} Hz (zero phase), then linear"
        if downsample
        else "linear interpolation"
    )
    note = f"resampled from {rate:.1f} Hz to {target_rate:g} Hz ({how})"
    if dropped:
        note += f"; {dropped} samples in stretches too short to filter left out"
    return Resampled(new, rate, note)


def _float_columns(samples: SampleArrays) -> dict[str, npt.NDArray[np.float64]]:
    return {
        f.name: getattr(samples, f.name)
        for f in dataclasses.fields(samples)
        if f.name != "stamp_ns" and getattr(samples, f.name) is not None
    }


def _resample_column(
    x: npt.NDArray[np.float64],
    y: npt.NDArray[np.float64],
    xq: npt.NDArray[np.float64],
    source_s: float,
    step_s: float,
    downsample: bool,
) -> npt.NDArray[np.float64]:
    """One column of a contiguous stretch, at the query times ``xq`` [ns from start]."""
    bad = ~np.isfinite(y)
    if bad.all():
        return np.full(xq.shape, np.nan)
    if bad.any():  # filter and interpolate through the holes, then put them back
        y = np.interp(x, x[~bad], y[~bad])
    if downsample:
        from scipy.signal import butter, sosfiltfilt

        cutoff_hz = CUTOFF_OF_NYQUIST * 0.5 / step_s
        sos = butter(_FILTER_ORDER, cutoff_hz, fs=1.0 / source_s, output="sos")
        y = sosfiltfilt(sos, y)
    out = np.interp(xq, x, y)
    if bad.any():
        # A new sample within one source step of a NaN is not known: NaN again.
        near_bad = np.interp(xq, x, bad.astype(np.float64)) > 0.0
        out[near_bad] = np.nan
    return out
