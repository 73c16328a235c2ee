"""Fine-tuning a merged model member by member: the weights between members stay zero.

A merged model (``sideslip-merge``) is one wide LSTM whose members no weight connects
(:mod:`sideslip_training.merge`). Trained as one dense network, every step of the
optimiser fills those zeros: the fine-tuned file is one group again, streams densely at
the wide network's cost (five 64-unit members: a 320-unit step, about 3x the members'
per-step work in the estimator's numba engine, docs/training.md), and training itself
multiplies the zeros too (a 320-unit recurrence is five times the arithmetic of five
64-unit ones).

:class:`MemberNet` holds the members as separate LSTMs whose outputs add up. Its
forward pass is the wide network's, term for term, so its gradients are the dense
network's gradients on the members' own weights; the weights between members are not
parameters at all and stay exactly zero. The head's bias is shared: only the first
member's is trained (the others' are fixed at zero), as the wide network has one.
:meth:`MemberNet.joined` writes the result back as the wide :class:`SideslipNet`.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from sideslip_msgs_py.model_members import joined_tensors, member_tensors, unit_groups

from .model import ModelConfig, SideslipNet


class MemberNet(nn.Module):
    """The members of a merged LSTM, each its own :class:`SideslipNet`; ``forward``
    maps z-scored windows (B, T, F) to the sum of their z-scored outputs, shape (B,)."""

    def __init__(self, config: ModelConfig, groups: list[np.ndarray]) -> None:
        super().__init__()
        if config.architecture != "lstm":
            raise ValueError(f"only a unidirectional lstm splits into members, not {config}")
        self.config = config
        self.groups = [np.asarray(g) for g in groups]
        self.members = nn.ModuleList(
            SideslipNet(ModelConfig("lstm", config.n_features, len(g), config.layers))
            for g in self.groups
        )
        for member in self.members[1:]:
            member.head.bias.requires_grad_(False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out = self.members[0](x)
        for member in self.members[1:]:
            out = out + member(x)
        return out

    def joined(self) -> SideslipNet:
        """The wide network these members are (zeros between them), on the CPU."""
        cfg = self.config
        members = [
            {k: v.detach().cpu().numpy() for k, v in m.state_dict().items()} for m in self.members
        ]
        tensors = joined_tensors(members, self.groups, cfg.hidden_units, cfg.layers)
        net = SideslipNet(cfg)
        net.load_state_dict({k: torch.from_numpy(v) for k, v in tensors.items()}, strict=True)
        return net


def split_members(net: SideslipNet) -> MemberNet | None:
    """``net`` as its members (copies of their weights), or None when its units do not
    split into groups no weight connects (one network, or a bilstm)."""
    cfg = net.config
    if cfg.architecture != "lstm":
        return None
    tensors = {k: v.detach().cpu().numpy() for k, v in net.state_dict().items()}
    groups = unit_groups(tensors, cfg.hidden_units, cfg.layers)
    if len(groups) < 2:
        return None
    out = MemberNet(cfg, groups)
    for n, (member, units) in enumerate(zip(out.members, groups, strict=True)):
        own = member_tensors(tensors, cfg.hidden_units, cfg.layers, units, head_bias=n == 0)
        member.load_state_dict({k: torch.from_numpy(v.copy()) for k, v in own.items()})
    return out.train(net.training)


__all__ = ["MemberNet", "split_members"]
