"""The pso_lstm back-end's ``torch`` engine: the network on one whole window per sample.

What ``sideslip_training``'s ``SideslipNet`` computes, bit for bit (the per-window path
the streaming engines are checked against). torch is imported when a
:class:`TorchWindow` is built, never by this module's import, so the default engines
and the other back-ends run without it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.artifact import ModelMetadata

from .base import BackendError


def _import_torch() -> Any:
    try:
        import torch
    except ImportError:
        msg = "pso_lstm needs PyTorch (pip install torch; the CPU wheel is enough)"
        raise BackendError(msg) from None
    return torch


class TorchWindow:
    """The network on one whole window with torch (the per-window path): what
    ``sideslip_training``'s ``SideslipNet`` computes, bit for bit."""

    def __init__(self, tensors: Mapping[str, np.ndarray], meta: ModelMetadata, threads: int):
        torch = _import_torch()
        torch.set_num_threads(threads)
        self._torch = torch
        self.meta = meta
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
        self._head = head
        # torch.lstm is what nn.LSTM.forward calls; calling it with the weights and a
        # zero state prepared once saves ~50 us of Python per sample at 400 Hz.
        self._weights = [w for layer in lstm.all_weights for w in layer]
        zeros = torch.zeros(meta.layers * meta.directions, 1, hidden)
        self._state = (zeros, zeros.clone())
        # The network input (float32, shared memory with the tensor fed to torch).
        self._input = torch.zeros(1, meta.window_steps, n_features, dtype=torch.float32)
        self._input_np = self._input.numpy()

    def __call__(self, z: npt.NDArray[np.float64]) -> float:
        """y of one window of z-scored inputs (window_steps, F), rounded to float32."""
        self._input_np[0] = z
        torch = self._torch
        with torch.inference_mode():
            output, _, _ = torch.lstm(
                self._input,
                self._state,
                self._weights,
                True,  # has_biases
                self.meta.layers,
                0.0,  # dropout
                False,  # train
                self.meta.directions == 2,
                True,  # batch_first
            )
            y = torch.nn.functional.linear(output[:, -1, :], self._head.weight, self._head.bias)
        return float(y.item())


def _prefixed(torch: Any, tensors: Mapping[str, np.ndarray], prefix: str) -> dict[str, Any]:
    return {
        name.removeprefix(prefix): torch.from_numpy(t)
        for name, t in tensors.items()
        if name.startswith(prefix)
    }
