"""Sliding-window LSTM/BiLSTM inference in numpy: one batched LSTM step per input row.

Semantics (those of :class:`~sideslip_estimator.backends.pso_lstm.PsoLstmBackend` and of
``sideslip_training``'s ``SideslipNet``): after each row, the output ``y`` (the z-scored
β) of the network on the window of the last ``window_steps`` (W) rows, every window run
from a zero hidden and cell state, its input rounded once to float32, the head reading
the top layer's output at the window's last step. β [rad] = y · beta_std + beta_mean
(+ the prior, if the model has one): :func:`sideslip_msgs_py.artifact.denormalize_beta`.

How: every window in flight (those that started at rows k − W + 1 … k) reads the same
new row, so their states are one batch of W columns and each row advances all of them
with one matrix product per layer (gates = W_ih·x + b_ih + b_hh + W_hh·h, gates in
PyTorch's order i, f, g, o), then the oldest window, which has now read W rows, gives
the output and its column restarts from zero for the window that starts at the next
row. The columns form a ring (window started at row k lives in column k mod W), so
nothing is copied or rolled. The work per row equals that of one window run step by
step (W steps of a (4H × H) matrix-vector product), done as one (4H × H)·(H × W) product.
Layer l > 0 reads layer l − 1's new hidden state of the same window, so stacked layers
advance layer by layer.

BiLSTM: the head reads the backward direction's output at the window's last step, which
has read only the last row (the backward pass starts there from a zero state), so for
one layer the backward half is one LSTM cell on the newest row: as cheap as the forward
half. With two or more layers, layer 1 reads the backward output of layer 0 at every
step of the window, which depends on where the window ends: nothing can be shared
between windows, and each row costs a full per-window pass of the layers above layer 0
(the layer-0 forward direction still streams; its per-window outputs are kept in a
history): 2·layers − 2 recurrences of W batch-1 steps in a Python loop, about twice
the time of the torch back-end's whole window (``bench/streaming.py --random
bilstm:2x64``), so such a model is better served by torch
(:attr:`StreamingLstm.per_window_recurrences` says which case applies).

Exactness: float64 arithmetic by default (the float32 weights and inputs convert
exactly), so the result is the network's exact output up to float64 rounding (~1e-16 in
y); the float32 torch path differs from it by its own float32 rounding (~1e-7). The
activations are exact identities, not approximations, evaluated over all four gates in
one numpy call thanks to gate rows pre-scaled by powers of two
(:class:`~sideslip_estimator.lstm_cells.Gates`).
``dtype=np.float32`` runs the same algorithm in float32, about twice as fast, with
errors of torch's own size (a few 1e-7 in y on the shipped models), not bit for bit.
``kernel="numba"`` (float32) advances the streamed layers with one compiled call per
layer (:func:`sideslip_estimator.lstm_kernel.lstm_step`: the sgemm plus a vectorised
fused cell update, activations in float64 with a rational tanh), 3-4× faster than the float32
numpy calls and within a few 1e-7 of torch's y.

A row with a NaN or an infinity (also one that overflows float32) gives NaN for the W
windows that hold it, and only for them: the row enters the states as zeros, which keeps
them finite (the numba kernel assumes finite values).

Rows before the window fills give no output; :meth:`StreamingLstm.reset` starts over.
This module imports no torch.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping
from typing import Final

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.artifact import (
    ArtifactError,
    ModelMetadata,
    expected_tensors,
    read_artifact,
)

from .lstm_cells import Direction, FloatArray, Gates

KERNELS: Final = ("numpy", "numba")
"""How the batched step is computed: numpy calls, or one compiled numba call."""


class StreamingLstm:
    """The network of a model artifact over a sliding window, one row at a time.

    ``push(row)`` takes the newest row of z-scored model inputs (float64, the
    metadata's ``features`` order: what :func:`sideslip_msgs_py.artifact.zscore`
    computes before its float32 rounding, which happens here) and returns ``y`` for the
    window of the last ``window_steps`` rows, or None until that many rows were pushed
    since construction or :meth:`reset`. Not thread-safe (preallocated buffers).
    """

    def __init__(
        self,
        tensors: Mapping[str, np.ndarray],
        meta: ModelMetadata,
        *,
        dtype: npt.DTypeLike = np.float64,
        kernel: str = "numpy",
    ) -> None:
        if kernel not in KERNELS:
            raise ValueError(f"StreamingLstm: kernel must be one of {KERNELS}, got {kernel!r}")
        self.kernel = kernel
        """``numpy`` (numpy calls, float64 or float32) or ``numba`` (the compiled fused
        step of :mod:`sideslip_estimator.lstm_kernel`, float32)."""
        if kernel == "numba":
            dtype = np.float32
        self.dtype = dt = np.dtype(dtype)
        """Arithmetic of the network: float64 (default, exact up to float64 rounding) or
        float32 (about twice as fast; rounds like, but not bit for bit as, torch)."""
        if dt not in (np.dtype(np.float64), np.dtype(np.float32)):
            raise ValueError(f"StreamingLstm: dtype must be float64 or float32, got {dt}")
        expected = expected_tensors(meta)
        for name, shape in expected.items():
            if name not in tensors:
                raise ArtifactError(f"StreamingLstm: tensor {name} is missing")
            if np.shape(tensors[name]) != shape:
                msg = (
                    f"StreamingLstm: tensor {name} has shape {np.shape(tensors[name])}, "
                    f"expected {shape}"
                )
                raise ArtifactError(msg)
        self.meta = meta
        self.window_steps = w = meta.window_steps
        self.hidden_units = h = meta.hidden_units
        self.layers = layers = meta.layers
        self.n_features = len(meta.features)
        self.bidirectional = meta.directions == 2
        self.per_window_recurrences = 2 * layers - 2 if self.bidirectional and layers > 1 else 0
        """Batch-1 recurrences over the whole window run per row (bilstm with 2+ layers);
        0 for every model that streams completely."""
        # Layers that stream: all of an lstm, layer 0's forward direction of a bilstm.
        # Their batched steps take the faster activation form of the dtype; the batch-1
        # steps (the rest) the tanh form, which needs fewer numpy calls.
        streamed = 1 if self.bidirectional else layers
        batched = "exp" if dt == np.float64 and kernel == "numpy" else "tanh"
        forward = [
            Direction.of(tensors, f"l{k}", h, dt, batched if k < streamed else "tanh")
            for k in range(layers)
        ]
        reverse = [
            Direction.of(tensors, f"l{k}_reverse", h, dt, "tanh")
            for k in range(layers if self.bidirectional else 0)
        ]
        head_w = np.asarray(tensors["head.weight"], dtype=np.float64).reshape(-1)
        self._head_fwd = np.ascontiguousarray(head_w[:h])
        self._head_bwd = np.ascontiguousarray(head_w[h:])
        self._head_b = float(np.asarray(tensors["head.bias"], dtype=np.float64)[0])
        self._forward, self._reverse = forward, reverse

        # The batch of in-flight windows, one column each. Rows: blocks [1; h_k] per
        # streamed layer k, so layer 0 reads [1; h_0] against [x-projection + bias | W_hh]
        # and layer k > 0 the contiguous rows [h_{k-1}; 1; h_k] against [W_ih | b | W_hh]:
        # biases and inputs ride in the matrix product, without a copy or an extra pass.
        block = h + 1
        self._z = np.zeros((streamed * block, w), dt)
        self._z[::block] = 1.0
        self._fresh = self._z[:, 0].copy()
        self._c = np.zeros((streamed, h, w), dt)
        self._gates = Gates(np.empty((4 * h, w), dt), h, forward[0].form)
        self._tmp = np.empty((h, w), dt)
        self._w_ih0 = forward[0].w_ih
        self._bias0 = forward[0].bias
        self._x32 = np.empty(self.n_features, dtype=np.float32)
        self._x = np.empty(self.n_features, dt)
        self._proj = np.empty(4 * h, dt)
        self._steps: list[tuple[FloatArray, FloatArray, FloatArray, FloatArray]] = []
        for k in range(streamed):
            if k == 0:
                m = np.concatenate([np.zeros((4 * h, 1), dt), forward[0].w_hh_t.T], axis=1)
                rows = self._z[0:block]
            else:
                d = forward[k]
                m = np.concatenate([d.w_ih, d.bias[:, None], d.w_hh_t.T], axis=1)
                rows = self._z[(k - 1) * block + 1 : (k + 1) * block]
            hidden_rows = self._z[k * block + 1 : (k + 1) * block]
            self._steps.append((np.ascontiguousarray(m), rows, self._c[k], hidden_rows))
        self._bias_column = self._steps[0][0][:, 0]
        self._top = self._steps[-1][3]
        self._step = self._push_first = None
        if kernel == "numba":
            from . import lstm_kernel  # compiles on first use: only when asked for

            lstm_kernel.compile_kernels()
            self._step = lstm_kernel.lstm_step
            self._push_first = lstm_kernel.push_first_layer
        self._bad_row = -w
        """The last row (count) that held a non-finite input."""

        if self.bidirectional:
            self._bwd_c = np.zeros(h, dt)
            self._bwd_h = np.empty(h, dt)
            self._bwd_tmp = np.empty(h, dt)
            self._bwd_gates = Gates(np.empty(4 * h, dt), h, reverse[0].form)
        if self.per_window_recurrences:
            # Layer 0's forward outputs of every window in flight, by (column, step), and
            # the last W rows twice over (row n at n mod W and n mod W + W) so the window
            # is one contiguous slice.
            self._history = np.zeros((w, w, h), dt)
            self._columns = np.arange(w)
            self._rows = np.zeros((2 * w, self.n_features), dt)
        self._n = 0

    @classmethod
    def from_artifact(
        cls,
        path: str | os.PathLike[str],
        *,
        dtype: npt.DTypeLike = np.float64,
        kernel: str = "numpy",
    ) -> StreamingLstm:
        """The engine of the artifact at ``path`` (:func:`read_artifact`'s checks and
        :class:`ArtifactError` naming the file)."""
        tensors, meta = read_artifact(path)
        return cls(tensors, meta, dtype=dtype, kernel=kernel)

    @property
    def rows_pushed(self) -> int:
        """Rows pushed since construction or :meth:`reset`."""
        return self._n

    def reset(self) -> None:
        """Forget every window in flight: the next output comes ``window_steps`` rows on."""
        self._z[:] = self._fresh[:, None]
        self._c[:] = 0.0
        self._n = 0
        self._bad_row = -self.window_steps

    def push(self, row: npt.ArrayLike) -> float | None:
        """Advance every window by ``row`` (F z-scored inputs, float64); ``y`` of the
        window ending at this row, or None while fewer than ``window_steps`` rows have
        been pushed since :meth:`reset`."""
        x32 = self._x32
        try:
            with np.errstate(over="ignore"):  # a value beyond float32 becomes inf: refused
                x32[:] = row
        except ValueError:
            msg = f"StreamingLstm.push: expected a row of {self.n_features} inputs, got "
            raise ValueError(msg + f"shape {np.shape(row)}") from None
        x = self._x
        x[:] = x32
        w, n = self.window_steps, self._n
        if not np.isfinite(x).all():
            # Zeros in its place keep every state finite (the numba kernel assumes it);
            # the windows holding this row answer NaN below.
            self._bad_row = n
            x[:] = 0.0
        start, done = n % w, (n + 1) % w
        gates, tmp = self._gates, self._tmp
        if self._push_first is not None:
            # One compiled call: the new window's column, layer 0's input projection and
            # step; then the layers above, one call each.
            m0 = self._steps[0][0]
            self._push_first(
                x, self._w_ih0, self._bias0, m0, self._z, self._fresh, self._c, gates.buffer, start
            )
            for m, rows, c, h_out in self._steps[1:]:
                self._step(m, rows, gates.buffer, c, h_out)
        else:
            # The window starting at this row takes the column of the one that finished.
            self._z[:, start] = self._fresh
            self._c[:, :, start] = 0.0
            np.matmul(self._w_ih0, x, out=self._proj)
            np.add(self._proj, self._bias0, out=self._bias_column)
            for m, rows, c, h_out in self._steps:
                np.matmul(m, rows, out=gates.buffer)
                gates.cell(c, tmp, h_out)
        if self.per_window_recurrences:
            self._history[self._columns, (n - self._columns) % w] = self._top.T
            self._rows[start] = x
            self._rows[start + w] = x
        self._n = n + 1
        if n + 1 < w:
            return None
        if n - self._bad_row < w:
            return math.nan
        if self.per_window_recurrences:
            return self._window_output(done)
        y = float(self._head_fwd @ self._top[:, done]) + self._head_b
        if self.bidirectional:
            # The backward direction's output at the last step: one cell on this row.
            d, c = self._reverse[0], self._bwd_c
            proj = self._bwd_gates.buffer
            np.matmul(d.w_ih, x, out=proj)
            np.add(proj, d.bias, out=proj)
            c[:] = 0.0
            self._bwd_gates.cell(c, self._bwd_tmp, self._bwd_h)
            y += float(self._head_bwd @ self._bwd_h)
        return y

    def _window_output(self, column: int) -> float:
        """y of the window in ``column`` (complete), for a bilstm of 2+ layers: layer 0's
        forward outputs from the history, every other direction run over the window."""
        w = self.window_steps
        start = (self._n - w) % w
        window = self._rows[start : start + w]
        fwd = self._history[column]
        bwd = self._reverse[0].run(window, reverse=True)
        for k in range(1, self.layers):
            inputs = np.concatenate([fwd, bwd], axis=1)
            top = k == self.layers - 1
            fwd = self._forward[k].run(inputs, reverse=False)
            # The top layer's backward output is read at the last step only.
            bwd = self._reverse[k].run(inputs, reverse=True, steps=1 if top else None)
        return float(self._head_fwd @ fwd[-1] + self._head_bwd @ bwd[-1]) + self._head_b

    def run(self, rows: Iterable[npt.ArrayLike]) -> FloatArray:
        """``push`` every row in order: y of each complete window (rows − W + 1 of them,
        counting the windows that include rows pushed before this call)."""
        out = [y for y in map(self.push, rows) if y is not None]
        return np.array(out, dtype=np.float64)


__all__ = ["KERNELS", "StreamingLstm"]
