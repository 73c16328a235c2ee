"""The LSTM cell pieces the streaming engine batches: gate tensors reordered and scaled so
that one elementwise function serves all four gates (:func:`reordered`), the in-place
cell update over a buffer of gate pre-activations (:class:`Gates`), and one direction of
one layer (:class:`Direction`). Pure numpy; see :mod:`sideslip_estimator.streaming` for
the algorithm and its exactness."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

TANH_SCALES: Final = (0.5, 0.5, 0.5, 1.0)
"""Row scales (i, f, o, g) for one tanh: σ(z) = ½·tanh(z/2) + ½, g = tanh(z)."""
EXP_SCALES: Final = (-1.0, -1.0, -1.0, -2.0)
"""Row scales (i, f, o, g) for one exp: σ(z) = 1/(1 + e^(−z)), g = tanh(z) = 2σ(2z) − 1."""


def reordered(tensor: np.ndarray, hidden: int, scales: tuple[float, ...]) -> FloatArray:
    """A gate-stacked tensor (4H on axis 0, PyTorch order i, f, g, o) as float64 in the
    order i, f, o, g, each gate's rows times its scale (a power of two: exact), so that
    one elementwise function over all 4H rows serves every gate (:class:`Gates`)."""
    t = np.asarray(tensor, dtype=np.float64)
    i, f, g, o = (t[k * hidden : (k + 1) * hidden] for k in range(4))
    return np.concatenate([s * v for s, v in zip(scales, (i, f, o, g), strict=True)])


class Gates:
    """A buffer of gate pre-activations (4H, …) in the order of :func:`reordered` and
    the LSTM cell update that reads it, in place and without allocating.

    Two exact forms of the activations (measured with numpy 2.4 on AVX-512):
    ``exp`` takes 1/(1 + e^(−z)) over all rows, then 2σ − 1 on g's rows: numpy's float64
    exp is twice as fast as its tanh, which makes a batched float64 step 6-8 % faster;
    ``tanh`` takes tanh over all rows, then ½·t + ½ on i, f, o's rows: faster in float32
    and for a single state (fewer numpy calls).
    """

    def __init__(self, buffer: FloatArray, hidden: int, form: str) -> None:
        h = hidden
        self.buffer = buffer
        self.exp = form == "exp"
        self.i, self.f, self.o, self.g = (buffer[k * h : (k + 1) * h] for k in range(4))
        self.sigmoid = buffer[: 3 * h]

    def cell(self, c: FloatArray, tmp: FloatArray, h_out: FloatArray) -> None:
        """c ← f·c + i·g, h_out ← o·tanh(c), from the pre-activations in the buffer
        (overwritten); batch (4H, W) and single state (4H,) alike."""
        a = self.buffer
        if self.exp:
            with np.errstate(over="ignore"):  # e^(−z) = inf gives σ = 0 exactly
                np.exp(a, out=a)
            np.add(a, 1.0, out=a)
            np.divide(1.0, a, out=a)
            np.multiply(self.g, 2.0, out=self.g)
            np.subtract(self.g, 1.0, out=self.g)
        else:
            np.tanh(a, out=a)
            np.multiply(self.sigmoid, 0.5, out=self.sigmoid)
            np.add(self.sigmoid, 0.5, out=self.sigmoid)
        np.multiply(self.f, c, out=c)
        np.multiply(self.i, self.g, out=tmp)
        np.add(c, tmp, out=c)
        np.tanh(c, out=tmp)
        np.multiply(self.o, tmp, out=h_out)


@dataclass(frozen=True)
class Direction:
    """One direction of one layer, in the gate order and scales of :func:`reordered`."""

    w_ih: FloatArray
    """(4H, inputs)"""
    w_hh_t: FloatArray
    """(H, 4H): W_hh transposed, for a batch-1 step h · W_hh^T"""
    bias: FloatArray
    """(4H,) b_ih + b_hh"""
    form: str
    """The activation form of :class:`Gates` the scales are for."""

    @classmethod
    def of(
        cls, tensors: Mapping[str, np.ndarray], name: str, hidden: int, dtype: np.dtype, form: str
    ) -> Direction:
        """The weights of ``lstm.*_{name}`` (name: ``l0``, ``l1_reverse``, ...) in ``dtype``
        (the bias sum in float64, then rounded), scaled for the activation ``form``."""
        scales = EXP_SCALES if form == "exp" else TANH_SCALES
        b = reordered(tensors[f"lstm.bias_ih_{name}"], hidden, scales)
        b += reordered(tensors[f"lstm.bias_hh_{name}"], hidden, scales)
        w_hh = reordered(tensors[f"lstm.weight_hh_{name}"], hidden, scales)
        return cls(
            reordered(tensors[f"lstm.weight_ih_{name}"], hidden, scales).astype(dtype),
            np.ascontiguousarray(w_hh.T, dtype=dtype),
            b.astype(dtype),
            form,
        )

    def run(self, inputs: FloatArray, *, reverse: bool, steps: int | None = None) -> FloatArray:
        """Hidden outputs (T, H) of this direction over ``inputs`` (T, inputs) from a
        zero state, batch 1, in the inputs' time order; with ``steps``, only the first
        ``steps`` processed (from the end when ``reverse``); the rest stay zero."""
        length, hidden, dtype = inputs.shape[0], self.w_hh_t.shape[0], self.bias.dtype
        projected = inputs @ self.w_ih.T
        projected += self.bias
        out = np.zeros((length, hidden), dtype)
        gates = Gates(np.empty(4 * hidden, dtype), hidden, self.form)
        c = np.zeros(hidden, dtype)
        tmp = np.empty(hidden, dtype)
        h = np.zeros(hidden, dtype)
        order = range(length - 1, -1, -1) if reverse else range(length)
        for n, t in enumerate(order):
            if steps is not None and n == steps:
                break
            np.matmul(h, self.w_hh_t, out=gates.buffer)
            np.add(gates.buffer, projected[t], out=gates.buffer)
            gates.cell(c, tmp, h)
            out[t] = h
        return out
