"""A fused float32 LSTM step over a batch of windows, compiled with numba.

One call does what :class:`~sideslip_estimator.streaming.StreamingLstm`'s numpy path
does in about ten numpy calls: the gate product (BLAS sgemm through ``np.dot``), the
four activations, the cell update and the new hidden state, in one pass over the
(4H × W) gates that LLVM vectorises (AVX2/AVX-512). On this project's 2-core VM it makes
the activations and cell update of an 80-unit, 100-window step 27 µs instead of about
60 µs; the sgemm (2.6 M multiply-adds, 57 µs: about this core's float32 FMA peak) is
then most of the step.

Why an own tanh: numba calls libm's scalar ``tanh`` (no SVML here), which stops the
loop from vectorising (2.6 ns per call, 5 calls per unit and window). :func:`tanh64`
is a rational function x·P(x²)/Q(x²), clamped at |x| = 10 (where tanh(x) differs from
1 by 4e-9), that vectorises; its coefficients are a weighted least-squares fit to tanh
on [0, 10] (``bench/tools/fit_tanh.py`` refits them; max error 7.7e-9). The gates are
read and the activations and cell update computed in float64, then the cell and hidden
state rounded to float32 (torch's state type): the result is as close to the exact
activations as numpy's float32 tanh (8e-8 against 6e-8 over a dense grid,
``tests/sideslip_estimator/test_lstm_kernel.py``). The same rational evaluated in
float32 would be twice as fast but 6 ulps off near ±1 and can exceed 1: measured, not
taken. σ(z) = ½·tanh(z/2) + ½, with the ½ inside folded into the gate rows by the caller
(a power of two: exact).

``fastmath`` lets LLVM contract multiply-adds and reorder; it also assumes no NaN or
infinity, so callers must not pass non-finite gates (the streaming engine replaces a
non-finite row by zeros and reports NaN for the windows holding it).
``error_model="numpy"`` removes Python's division-by-zero check, without which the loop
does not vectorise (Q(x²) ≥ 1, so there is no such division anyway).

Compiled on first use (about 1 s; cached on disk by numba where the package folder or
the user cache is writable). This module imports no torch and no rclpy.
"""

from __future__ import annotations

from typing import Final

import numba
import numpy as np
import numpy.typing as npt

Float32Array = npt.NDArray[np.float32]

TANH_CLAMP: Final = 10.0
"""|x| beyond which :func:`tanh64` returns its value at ±10 (1 − 4e-9)."""
TANH_P: Final = (
    0.9999999813652202,
    0.1362691854722271,
    0.003802378587634535,
    2.6706550654771277e-05,
    2.758720712872739e-08,
    -1.0110288381828798e-11,
)
"""Numerator coefficients of :func:`tanh64` in powers of x² (degree 0 first)."""
TANH_Q: Final = (
    1.0,
    0.4696024429074353,
    0.027003283100978808,
    0.0003823388483902615,
    1.1981681154503086e-06,
)
"""Denominator coefficients of :func:`tanh64` in powers of x² (degree 0 first)."""

_P0, _P1, _P2, _P3, _P4, _P5 = TANH_P
_Q0, _Q1, _Q2, _Q3, _Q4 = TANH_Q
_HI: Final = TANH_CLAMP
_LO: Final = -TANH_CLAMP

_FLAGS: Final = {"fastmath": True, "error_model": "numpy", "cache": True}


@numba.njit(inline="always", **_FLAGS)
def tanh64(x: float) -> float:
    """tanh(x) in float64 arithmetic (max error 7.7e-9, odd, |result| < 1)."""
    x = _HI if x > _HI else x
    x = _LO if x < _LO else x
    t = x * x
    p = ((((_P5 * t + _P4) * t + _P3) * t + _P2) * t + _P1) * t + _P0
    q = (((_Q4 * t + _Q3) * t + _Q2) * t + _Q1) * t + _Q0
    return x * p / q


@numba.njit(**_FLAGS)
def tanh_array(x: Float32Array, out: Float32Array) -> None:
    """:func:`tanh64` over a 1-D float32 array, rounded to float32 (what the step does
    to the cell state; for tests)."""
    for k in range(x.shape[0]):
        out[k] = np.float32(tanh64(np.float64(x[k])))


@numba.njit(**_FLAGS)
def lstm_step(
    weights: Float32Array,
    inputs: Float32Array,
    gates: Float32Array,
    cell: Float32Array,
    hidden_out: Float32Array,
) -> None:
    """One LSTM step of W windows at once, in place.

    ``weights`` (4H × K) times ``inputs`` (K × W: each window's input, bias row and
    previous hidden state stacked, as the caller lays them out) gives the gates (4H × W)
    in the order i, f, o, g with the rows of i, f, o pre-scaled by ½; then
    c ← σ(f)·c + σ(i)·tanh(g) in ``cell`` (H × W) and h = σ(o)·tanh(c) into
    ``hidden_out`` (H × W, may be rows of ``inputs``: they are read before written).
    All arrays C-contiguous float32.
    """
    np.dot(weights, inputs, gates)
    units = cell.shape[0]
    windows = cell.shape[1]
    for j in range(units):
        gate_i = gates[j]
        gate_f = gates[units + j]
        gate_o = gates[2 * units + j]
        gate_g = gates[3 * units + j]
        c = cell[j]
        h = hidden_out[j]
        for w in range(windows):
            i = 0.5 * tanh64(np.float64(gate_i[w])) + 0.5
            f = 0.5 * tanh64(np.float64(gate_f[w])) + 0.5
            o = 0.5 * tanh64(np.float64(gate_o[w])) + 0.5
            c_new = np.float32(f * np.float64(c[w]) + i * tanh64(np.float64(gate_g[w])))
            c[w] = c_new
            h[w] = np.float32(o * tanh64(np.float64(c_new)))


@numba.njit(**_FLAGS)
def push_first_layer(
    x: Float32Array,
    input_weights: Float32Array,
    bias: Float32Array,
    weights: Float32Array,
    states: Float32Array,
    fresh: Float32Array,
    cells: Float32Array,
    gates: Float32Array,
    column: int,
) -> None:
    """Start a window in ``column`` and advance the first layer of every window by ``x``.

    ``states`` (rows × W) holds every streamed layer's [1; h] block (layer 0's first);
    its ``column`` becomes ``fresh`` and the cells' (layers × H × W) column zero: the
    window that starts with this row. Column 0 of ``weights`` (layer 0's
    [x-projection + bias | W_hh], 4H × (H + 1)) becomes W_ih·x + bias (float32, as
    torch adds them); then one :func:`lstm_step` of layer 0.
    """
    for r in range(states.shape[0]):
        states[r, column] = fresh[r]
    for k in range(cells.shape[0]):
        for j in range(cells.shape[1]):
            cells[k, j, column] = 0.0
    for g in range(input_weights.shape[0]):
        acc = np.float32(0.0)
        for f in range(x.shape[0]):
            acc += input_weights[g, f] * x[f]
        weights[g, 0] = acc + bias[g]
    block = weights.shape[1]
    lstm_step(weights, states[:block], gates, cells[0], states[1:block])


def compile_kernels() -> None:
    """Compile (or load from numba's cache) the kernels now, on tiny arrays, so the
    first real step is not delayed by the compiler."""
    z = np.zeros((4, 1), np.float32)
    lstm_step(np.zeros((4, 2), np.float32), np.zeros((2, 1), np.float32), z, z[:1], z[1:2])
    states = np.zeros((2, 1), np.float32)
    push_first_layer(
        np.zeros(1, np.float32),
        np.zeros((4, 1), np.float32),
        np.zeros(4, np.float32),
        np.zeros((4, 2), np.float32),
        states,
        states[:, 0].copy(),
        np.zeros((1, 1, 1), np.float32),
        z,
        0,
    )
    tanh_array(np.zeros(1, np.float32), np.zeros(1, np.float32))


__all__ = [
    "TANH_CLAMP",
    "TANH_P",
    "TANH_Q",
    "compile_kernels",
    "lstm_step",
    "push_first_layer",
    "tanh64",
]
