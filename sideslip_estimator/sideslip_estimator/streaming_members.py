"""A merged model streamed member by member: the same output for a fraction of the work.

``sideslip-merge`` writes the mean of several networks as one wider LSTM whose weights
between members are zero (``sideslip_training.merge``). Run densely, every step still
multiplies those zeros: five 64-unit members make a 320-unit LSTM, whose batched step is
a (1280 × 321)·(321 × W) product, five times the (256 × 65)·(65 × W) products of the
members themselves. :func:`streaming_engine` finds the groups of hidden units that no
weight connects (recurrent weights of every layer and the input weights of the layers
above the first), and when there are several, runs one :class:`StreamingLstm` per group
and sums their outputs (:class:`MemberSum`). The head is linear, so the sum is the wide
network's y; only the float32 rounding order of the gate products changes (a product
with an exact zero adds nothing), within the few 1e-7 the float32 engines already differ
from torch by.

The groups are read from the weights, not from the file's provenance: any model whose
units split this way is served, and a fine-tuned merged model whose zero blocks filled
in is one group again and streams densely. A bilstm streams densely (its backward
direction reads every unit of the layer below).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.artifact import ModelMetadata, expected_tensors

from .lstm_cells import FloatArray
from .streaming import StreamingLstm


def unit_groups(tensors: Mapping[str, np.ndarray], meta: ModelMetadata) -> list[np.ndarray]:
    """Index arrays of the hidden units (ascending, the groups in order of their first
    unit) such that no weight connects units of two groups in any layer: the members of
    a merged model. One group of every unit for a bilstm or a network no zeros split."""
    h = meta.hidden_units
    if meta.directions != 1:
        return [np.arange(h)]
    coupled = np.zeros((h, h), dtype=bool)
    for k in range(meta.layers):
        names = [f"lstm.weight_hh_l{k}"] + ([f"lstm.weight_ih_l{k}"] if k > 0 else [])
        for name in names:
            # Unit j's four gate rows against unit m's column (the gates stack i, f, g, o).
            weights = np.asarray(tensors[name]).reshape(4, h, h)
            coupled |= np.any(weights != 0.0, axis=0)
    coupled |= coupled.T
    # Connected components by a plain search: scipy's csgraph would do it, but scipy is
    # only in the ukf extra, and the pso_lstm back-end must not need it.
    group = np.full(h, -1)
    for seed in range(h):
        if group[seed] >= 0:
            continue
        group[seed] = seed
        frontier = [seed]
        while frontier:
            unit = frontier.pop()
            for other in np.flatnonzero(coupled[unit] & (group < 0)):
                group[other] = seed
                frontier.append(int(other))
    return [np.flatnonzero(group == g) for g in dict.fromkeys(group.tolist())]


def member_tensors(
    tensors: Mapping[str, np.ndarray], meta: ModelMetadata, units: np.ndarray, *, head_bias: bool
) -> dict[str, np.ndarray]:
    """The tensors of the network of ``units`` alone (a unidirectional lstm): their gate
    rows, their recurrent and upper-layer input columns, their head weights; the head's
    bias only where ``head_bias`` (exactly one group carries it)."""
    h = meta.hidden_units
    rows = np.concatenate([g * h + units for g in range(4)])
    out: dict[str, np.ndarray] = {}
    for k in range(meta.layers):
        w_ih = np.asarray(tensors[f"lstm.weight_ih_l{k}"])[rows]
        out[f"lstm.weight_ih_l{k}"] = w_ih if k == 0 else w_ih[:, units]
        out[f"lstm.weight_hh_l{k}"] = np.asarray(tensors[f"lstm.weight_hh_l{k}"])[rows][:, units]
        for b in ("bias_ih", "bias_hh"):
            out[f"lstm.{b}_l{k}"] = np.asarray(tensors[f"lstm.{b}_l{k}"])[rows]
    out["head.weight"] = np.asarray(tensors["head.weight"])[:, units]
    bias = np.asarray(tensors["head.bias"])
    out["head.bias"] = bias if head_bias else np.zeros_like(bias)
    return {name: np.ascontiguousarray(t) for name, t in out.items()}


class MemberSum:
    """:class:`StreamingLstm`'s interface over the unit groups of a merged model: every
    row pushed into one engine per group, ``y`` the sum of theirs (None while the
    window fills, NaN for windows holding a non-finite row, as one engine gives)."""

    def __init__(
        self,
        tensors: Mapping[str, np.ndarray],
        meta: ModelMetadata,
        groups: list[np.ndarray],
        *,
        dtype: npt.DTypeLike = np.float64,
        kernel: str = "numpy",
    ) -> None:
        self.meta = meta
        self.groups = groups
        """The hidden units each engine runs (indices into the file's units)."""
        self.engines = [
            StreamingLstm(
                member_tensors(tensors, meta, units, head_bias=n == 0),
                dataclasses.replace(meta, hidden_units=len(units)),
                dtype=dtype,
                kernel=kernel,
            )
            for n, units in enumerate(groups)
        ]
        first = self.engines[0]
        self.kernel, self.dtype = first.kernel, first.dtype
        self.window_steps = first.window_steps
        self.hidden_units = meta.hidden_units
        self.layers = meta.layers
        self.n_features = first.n_features
        self.bidirectional = False
        self.per_window_recurrences = 0

    @property
    def rows_pushed(self) -> int:
        return self.engines[0].rows_pushed

    def reset(self) -> None:
        for engine in self.engines:
            engine.reset()

    def push(self, row: npt.ArrayLike) -> float | None:
        outputs = [engine.push(row) for engine in self.engines]
        if outputs[0] is None:
            return None
        return float(sum(outputs))  # type: ignore[arg-type]

    def run(self, rows: Iterable[npt.ArrayLike]) -> FloatArray:
        out = [y for y in map(self.push, rows) if y is not None]
        return np.array(out, dtype=np.float64)


def streaming_engine(
    tensors: Mapping[str, np.ndarray],
    meta: ModelMetadata,
    *,
    dtype: npt.DTypeLike = np.float64,
    kernel: str = "numpy",
) -> StreamingLstm | MemberSum:
    """The streaming engine for a model: per member (:class:`MemberSum`) where its
    units split into groups no weight connects, else one :class:`StreamingLstm`."""
    shapes = expected_tensors(meta)
    # Tensors that do not fit go straight to StreamingLstm, whose error names them.
    fits = all(n in tensors and np.shape(tensors[n]) == s for n, s in shapes.items())
    if fits and meta.directions == 1:
        groups = unit_groups(tensors, meta)
        if len(groups) > 1:
            return MemberSum(tensors, meta, groups, dtype=dtype, kernel=kernel)
    return StreamingLstm(tensors, meta, dtype=dtype, kernel=kernel)


__all__ = ["MemberSum", "member_tensors", "streaming_engine", "unit_groups"]
