"""The sideslip network of the paper's Fig. 5: an LSTM (or BiLSTM) over a window, then a
fully connected layer on the result at the window's last step.

Input: a batch of windows (B, T, F), oldest step first, every feature z-scored with the
training statistics (:func:`sideslip_msgs_py.artifact.zscore`). Output: (B,) z-scored β
at the last step; β [rad] = output · beta_std + beta_mean. The attribute names ``lstm``
and ``head`` are the tensor names of the model artifact
(:func:`sideslip_msgs_py.artifact.expected_tensors`); do not rename them.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

ARCHITECTURES = ("lstm", "bilstm")


@dataclass(frozen=True)
class ModelConfig:
    """Shape of the network: everything needed to rebuild it (weights aside)."""

    architecture: str = "lstm"  # lstm | bilstm
    n_features: int = 6  # F: input channels per step (the paper's six)
    hidden_units: int = 64  # H per direction (PSO tunes it in the paper)
    layers: int = 1  # stacked LSTM layers

    def __post_init__(self) -> None:
        if self.architecture not in ARCHITECTURES:
            msg = f"unknown architecture {self.architecture!r} (known: {', '.join(ARCHITECTURES)})"
            raise ValueError(msg)
        for name in ("n_features", "hidden_units", "layers"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"ModelConfig.{name} must be an integer >= 1, got {value!r}")

    @property
    def directions(self) -> int:
        return 2 if self.architecture == "bilstm" else 1


class SideslipNet(nn.Module):
    """LSTM/BiLSTM + fully connected head; ``forward`` maps (B, T, F) → (B,)."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        self.config = config
        self.lstm = nn.LSTM(
            input_size=config.n_features,
            hidden_size=config.hidden_units,
            num_layers=config.layers,
            batch_first=True,
            bidirectional=config.architecture == "bilstm",
        )
        self.head = nn.Linear(config.directions * config.hidden_units, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """z-scored windows (B, T, F), float32 → z-scored β at step T, shape (B,).

        The head reads the top layer's output at the last step, as MATLAB's
        ``OutputMode='last'``: for bilstm, the forward direction's state after the whole
        window concatenated with the backward direction's state at that step (which has
        seen only the last row, since the backward pass starts there).
        """
        output, _ = self.lstm(x)  # (B, T, directions · H)
        return self.head(output[:, -1, :]).squeeze(-1)
