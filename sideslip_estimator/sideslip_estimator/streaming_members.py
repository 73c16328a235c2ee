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
in is one group again and streams densely (the groups and each member's tensors:
``sideslip_msgs_py.model_members``). A bilstm streams densely (its backward
direction reads every unit of the layer below).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py import model_members
from sideslip_msgs_py.artifact import ModelMetadata, expected_tensors
from sideslip_msgs_py.model_members import member_tensors

from .lstm_cells import FloatArray
from .streaming import StreamingLstm


def numba_available() -> bool:
    """Whether numba imports (an optional dependency of the streaming engine's kernel)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def unit_groups(tensors: Mapping[str, np.ndarray], meta: ModelMetadata) -> list[np.ndarray]:
    """The groups of hidden units no weight connects: the members of a merged model
    (:func:`sideslip_msgs_py.model_members.unit_groups`)."""
    return model_members.unit_groups(tensors, meta.hidden_units, meta.layers, meta.directions)


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
                member_tensors(tensors, meta.hidden_units, meta.layers, units, head_bias=n == 0),
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


__all__ = ["MemberSum", "streaming_engine", "unit_groups"]
