"""Y_a's scale and bias measured while driving: :mod:`.accelerometer_scale`, sample by sample.

The offline fit filters whole stretches of driving, cuts them into chunks and adds up
the chunks' normal equations. Online, every sample updates the integrals ∫ Y_a dt and
∫ v_x ψ̇ dt (trapezoids, at the input rate) and a running mean over blocks of
:data:`BLOCK_S`; the block means of all columns alike (a linear filter that keeps the
fit's identity, and an anti-aliasing one) are kept at about 20 Hz. Once a chunk of
:data:`CHUNK_S` and :data:`MARGIN_S` after it have arrived, the kept rows (with up to
:data:`MARGIN_S` before the chunk) are filtered and the chunk's sums join the estimate:
the margins let the zero-phase filters settle, so the chunk is fitted as the offline fit
over the whole stretch would fit it. A sample costs about 1.3 µs and the sample that
closes a chunk 1.5–3 ms, whatever the input rate (``bench/imu_scale.py``): under one
400-Hz sample period, once a minute. A stretch ends at a gap, a stamp that goes back or
a non-finite value; what is left of it then becomes a chunk of its own (the last chunk
of a stretch takes up to :data:`CHUNK_S` + :data:`MARGIN_S`).
tests/sideslip_estimator/test_online_accelerometer_scale.py holds the two fits to each
other.

The estimate keeps the latest ``memory_chunks`` chunks, and it forgets the older ones at
once when the latest :data:`RECENT_CHUNKS` disagree with them beyond their spreads (an
IMU remounted or replaced): the scale then comes from the new mounting only. The chunks
are the state that a restart keeps (:meth:`~OnlineAccelerometerScale.state`,
:meth:`~OnlineAccelerometerScale.restore`).
"""

from __future__ import annotations

import importlib
import math
from collections import deque
from collections.abc import Mapping
from typing import Any, Final

import numpy as np

from sideslip_msgs_py.messages import NS_PER_S

from .accelerometer_scale import (
    CHUNK_S,
    MIN_ROWS,
    AccelerometerScale,
    ChunkSums,
    StretchColumns,
    chunk_sums,
    solve,
)

BLOCK_S: Final = 0.05
"""The rows kept are means over blocks of this [s] (20 Hz: ten times the fastest filter's
corner; a 50-ms boxcar passes the fitted band, below 0.5 Hz, within 0.1 %)."""

MARGIN_S: Final = 10.0
"""Rows [s] filtered either side of a chunk and not fitted, for the filters to settle
(the 0.5-Hz second-order low-pass's transient is below 1e-6 after about 6 s)."""
RECENT_CHUNKS: Final = 5
"""A change of mounting is looked for between this many latest chunks and the older."""
MIN_CHANGE: Final = 0.02
"""A change of scale smaller than this is never called a remount (the memory washes it
out instead); a larger one is when it exceeds :data:`CHANGE_SIGMAS` combined spreads."""
CHANGE_SIGMAS: Final = 5.0
STATE_VERSION: Final = 1
_COLUMNS: Final = 7  # the StretchColumns, in their order


class StateError(ValueError):
    """A stored state that cannot be used (the message names what is wrong)."""


class OnlineAccelerometerScale:
    """Feed it accepted samples in stamp order (:meth:`add`); :attr:`estimate` follows.

    ``max_gap_s``: a longer step (or one that goes back) ends the stretch. Not
    thread-safe.
    """

    def __init__(self, *, fit_bias: bool = True, memory_chunks: int = 30, max_gap_s: float = 0.5):
        if memory_chunks < 2 * RECENT_CHUNKS:
            raise ValueError(f"memory_chunks must be >= {2 * RECENT_CHUNKS}, got {memory_chunks}")
        if not (math.isfinite(max_gap_s) and max_gap_s > 0.0):
            raise ValueError(f"max_gap_s must be finite and > 0, got {max_gap_s!r}")
        # The fit's filters (scipy.signal, about 0.8 s to import) load here, before a node
        # subscribes: neither in the callback whose sample first closes a chunk nor in a
        # thread beside the first callbacks (under load that lost the soak's first 16
        # messages before the time line started, unreported).
        importlib.import_module("scipy.signal")
        self.fit_bias = fit_bias
        self.memory_chunks = memory_chunks
        self.chunks: deque[ChunkSums] = deque(maxlen=memory_chunks)
        self.estimate: AccelerometerScale | None = None
        self.remounts = 0
        """Times the latest chunks disagreed with the older ones, which were forgotten."""
        self.completed = 0
        """Chunks completed since this object was made (a state to save when it grows)."""
        self._max_gap_ns = round(max_gap_s * NS_PER_S)
        self._rows: list[tuple[float, ...]] = []  # block means, StretchColumns order
        self._start_ns = 0  # the stretch's first stamp: t is counted from it
        self._last: tuple[int, float, float, float] | None = None  # stamp, u, r, Y_a
        self._i_y = self._i_ur = 0.0  # the integrals up to the last sample
        self._block = [0.0] * _COLUMNS  # sums over the open block
        self._block_n = 0
        self._block_end_s = BLOCK_S
        self._chunk_start_s: float | None = None  # where the open chunk begins [s]

    # --- samples ----------------------------------------------------------------------
    def add(self, stamp_ns: int, v_x_mps: float, yaw_rate_radps: float, y_a_mps2: float) -> None:
        """One sample as recorded (X_v, ψ̇, Y_a before any correction). A non-finite one
        ends the stretch, as a gap does."""
        last = self._last
        if last is not None and not 0 < stamp_ns - last[0] <= self._max_gap_ns:
            self.end_stretch()
            last = None
        if not all(map(math.isfinite, (v_x_mps, yaw_rate_radps, y_a_mps2))):
            self.end_stretch()
            return
        if last is None:
            self._start_ns = stamp_ns
        else:
            dt = (stamp_ns - last[0]) * 1e-9
            self._i_y += 0.5 * (y_a_mps2 + last[3]) * dt
            self._i_ur += 0.5 * (v_x_mps * yaw_rate_radps + last[1] * last[2]) * dt
        self._last = (stamp_ns, v_x_mps, yaw_rate_radps, y_a_mps2)
        t = (stamp_ns - self._start_ns) * 1e-9
        if t >= self._block_end_s and self._block_n:
            self._close_block()
            # Blocks on a fixed grid from the stretch's start (one ends after a hole).
            self._block_end_s = (math.floor(t / BLOCK_S) + 1) * BLOCK_S
        b = self._block
        for i, value in enumerate(
            (t, self._i_y, self._i_ur, y_a_mps2, yaw_rate_radps, v_x_mps, v_x_mps * yaw_rate_radps)
        ):
            b[i] += value
        self._block_n += 1

    def _close_block(self) -> None:
        n = self._block_n
        row = tuple(v / n for v in self._block)
        self._rows.append(row)
        self._block = [0.0] * _COLUMNS
        self._block_n = 0
        if self._chunk_start_s is None:
            self._chunk_start_s = row[0]
        elif row[0] - self._chunk_start_s >= CHUNK_S + MARGIN_S:
            self._close_chunk(self._chunk_start_s + CHUNK_S)

    def end_stretch(self) -> None:
        """The driving stopped (a gap, a restart, shutdown): what is kept since the open
        chunk's start becomes a chunk, and the next sample starts a new stretch. The
        open block (under :data:`BLOCK_S`) is left out."""
        # (Fewer rows than a chunk needs are dropped: the filters need some to pad.)
        if self._chunk_start_s is not None and len(self._rows) >= MIN_ROWS:
            self._close_chunk(None)
        self._rows.clear()
        self._last = None
        self._i_y = self._i_ur = 0.0
        self._block = [0.0] * _COLUMNS
        self._block_n = 0
        self._block_end_s = BLOCK_S
        self._chunk_start_s = None

    def _close_chunk(self, end_s: float | None) -> None:
        """Fit the open chunk (up to ``end_s``, None: all kept) with its margins and
        start the next one at ``end_s``."""
        start = self._chunk_start_s
        assert start is not None
        rows = np.asarray(self._rows, dtype=float)
        t = rows[:, 0]
        in_chunk = t >= start
        if end_s is not None:
            in_chunk &= t < end_s
        cols = StretchColumns(*rows.T)
        found = chunk_sums(cols, np.where(in_chunk, 0, -1), fit_bias=self.fit_bias)
        for chunk in found:
            self.chunks.append(chunk)
            self.completed += 1
            self._look_for_remount()
        if found:
            self.estimate = solve(list(self.chunks), fit_bias=self.fit_bias)
        if end_s is None:
            return
        # Keep the margin before the next chunk.
        del self._rows[: int(np.searchsorted(t, end_s - MARGIN_S))]
        self._chunk_start_s = end_s

    def _look_for_remount(self) -> None:
        """Forget the older chunks when the latest few measure another scale."""
        if len(self.chunks) < 2 * RECENT_CHUNKS:
            return
        chunks = list(self.chunks)
        recent = solve(chunks[-RECENT_CHUNKS:], fit_bias=self.fit_bias)
        older = solve(chunks[:-RECENT_CHUNKS], fit_bias=self.fit_bias)
        if recent is None or older is None:
            return
        if not (math.isfinite(recent.spread) and math.isfinite(older.spread)):
            return
        change = abs(recent.scale - older.scale)
        if change > max(MIN_CHANGE, CHANGE_SIGMAS * math.hypot(recent.spread, older.spread)):
            for _ in range(len(chunks) - RECENT_CHUNKS):
                self.chunks.popleft()
            self.remounts += 1

    # --- state ------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """The chunks as plain data (JSON or YAML): what a restart needs to go on."""
        return {
            "version": STATE_VERSION,
            "fit_bias": self.fit_bias,
            "remounts": self.remounts,
            "chunks": [
                {
                    "xtx": c.xtx.tolist(),
                    "xty": c.xty.tolist(),
                    "samples": c.samples,
                    "cornering_s": c.cornering_s,
                }
                for c in self.chunks
            ],
        }

    def restore(self, state: Mapping[str, Any]) -> None:
        """Take the chunks of :meth:`state` (the latest ``memory_chunks`` of them).

        Raises :class:`StateError` naming what is wrong; nothing is changed then."""
        if not isinstance(state, Mapping) or state.get("version") != STATE_VERSION:
            raise StateError(f"not a version-{STATE_VERSION} IMU scale state")
        if bool(state.get("fit_bias")) != self.fit_bias:
            raise StateError(f"stored with fit_bias {state.get('fit_bias')}, not {self.fit_bias}")
        width = 4 if self.fit_bias else 3
        chunks = []
        for i, c in enumerate(state.get("chunks") or []):
            try:
                xtx = np.asarray(c["xtx"], dtype=float)
                xty = np.asarray(c["xty"], dtype=float)
                chunk = ChunkSums(xtx, xty, int(c["samples"]), float(c["cornering_s"]))
            except (KeyError, TypeError, ValueError) as err:
                raise StateError(f"chunk {i}: {err!r}") from None
            if xtx.shape != (width, width) or xty.shape != (width,):
                raise StateError(f"chunk {i}: sums of shape {xtx.shape}, {xty.shape}")
            if not (np.isfinite(xtx).all() and np.isfinite(xty).all()):
                raise StateError(f"chunk {i}: non-finite sums")
            chunks.append(chunk)
        self.chunks.clear()
        self.chunks.extend(chunks)
        self.remounts = int(state.get("remounts", 0))
        self.estimate = solve(list(self.chunks), fit_bias=self.fit_bias) if chunks else None
