"""The pso_lstm back-end's ``torch`` engine: the network on one whole window per sample.

What ``sideslip_training``'s ``SideslipNet`` computes, bit for bit (the per-window path
the streaming engines are checked against); a merged model member by member. torch is
imported when a :class:`TorchWindow` is built, never by this module's import, so the
default engines and the other back-ends run without it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.artifact import ModelMetadata
from sideslip_msgs_py.model_members import member_tensors

from ..streaming_members import unit_groups
from .base import BackendError


def _import_torch() -> Any:
    try:
        import torch
    except ImportError:
        msg = "pso_lstm needs PyTorch (pip install torch; the CPU wheel is enough)"
        raise BackendError(msg) from None
    return torch


class _WindowLstm:
    """One unidirectional or bidirectional LSTM and its head on a whole window."""

    def __init__(self, torch: Any, tensors: Mapping[str, np.ndarray], meta: ModelMetadata):
        n_features, hidden = len(meta.features), meta.hidden_units
        lstm = torch.nn.LSTM(
            n_features,
            hidden,
            num_layers=meta.layers,
            batch_first=True,
            bidirectional=meta.directions == 2,
        )
        head = torch.nn.Linear(meta.directions * hidden, 1)
        lstm.load_state_dict(_prefixed(torch, tensors, "lstm."), strict=True)
        head.load_state_dict(_prefixed(torch, tensors, "head."), strict=True)
        lstm.eval().requires_grad_(False)
        head.eval().requires_grad_(False)
        self._torch = torch
        self._head = head
        self._layers, self._bidirectional = meta.layers, meta.directions == 2
        # torch.lstm is what nn.LSTM.forward calls; calling it with the weights and a
        # zero state prepared once saves ~50 us of Python per sample at 400 Hz.
        self._weights = [w for layer in lstm.all_weights for w in layer]
        zeros = torch.zeros(meta.layers * meta.directions, 1, hidden)
        self._state = (zeros, zeros.clone())

    def __call__(self, window: Any) -> Any:
        """The head's output (1, 1) on ``window`` (1, T, F), under inference mode."""
        output, _, _ = self._torch.lstm(
            window,
            self._state,
            self._weights,
            True,  # has_biases
            self._layers,
            0.0,  # dropout
            False,  # train
            self._bidirectional,
            True,  # batch_first
        )
        return self._torch.nn.functional.linear(
            output[:, -1, :], self._head.weight, self._head.bias
        )


class TorchWindow:
    """The network on one whole window with torch (the per-window path): what
    ``sideslip_training``'s ``SideslipNet`` computes, bit for bit.

    A merged model (``sideslip-merge``: members no weight connects, found from the
    weights by :func:`~sideslip_estimator.streaming_members.unit_groups`) runs member by
    member and sums the heads, as the streaming engines do: five 64-unit members cost
    five 64-unit recurrences instead of one 320-unit one. That is the wide network's y
    up to the float32 rounding order of the sum (an exact zero adds nothing), not bit
    for bit."""

    def __init__(self, tensors: Mapping[str, np.ndarray], meta: ModelMetadata, threads: int):
        torch = _import_torch()
        torch.set_num_threads(threads)
        self._torch = torch
        self.meta = meta
        groups = unit_groups(tensors, meta)
        self.members = len(groups)
        """How many separate LSTMs run (1 unless the model is a merged one)."""
        if len(groups) == 1:
            self._nets = [_WindowLstm(torch, tensors, meta)]
        else:
            self._nets = [
                _WindowLstm(
                    torch,
                    member_tensors(
                        tensors, meta.hidden_units, meta.layers, units, head_bias=n == 0
                    ),
                    dataclasses.replace(meta, hidden_units=len(units)),
                )
                for n, units in enumerate(groups)
            ]
        # The network input (float32, shared memory with the tensor fed to torch).
        self._input = torch.zeros(1, meta.window_steps, len(meta.features), dtype=torch.float32)
        self._input_np = self._input.numpy()

    def __call__(self, z: npt.NDArray[np.float64]) -> float:
        """y of one window of z-scored inputs (window_steps, F), rounded to float32."""
        self._input_np[0] = z
        with self._torch.inference_mode():
            y = self._nets[0](self._input)
            for net in self._nets[1:]:
                y = y + net(self._input)
        return float(y.item())


def _prefixed(torch: Any, tensors: Mapping[str, np.ndarray], prefix: str) -> dict[str, Any]:
    return {
        name.removeprefix(prefix): torch.from_numpy(t)
        for name, t in tensors.items()
        if name.startswith(prefix)
    }
