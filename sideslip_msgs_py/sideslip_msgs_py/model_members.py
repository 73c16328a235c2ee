"""The members of a merged model, read from its weights: groups of hidden units that no
weight connects, and each group's own tensors.

``sideslip-merge`` writes the mean of several LSTMs as one wider LSTM whose weights
between members are zero (``sideslip_training.merge``). The estimator streams such a
model member by member (``sideslip_estimator.streaming_members``) and fine-tuning trains
it member by member (``sideslip_training.member_net``); both find the members here, from
the weights alone, so any model whose units split this way is served and a model whose
zero blocks filled in is one group again.

Tensor names and shapes are the artifact's (:func:`sideslip_msgs_py.artifact.expected_tensors`):
the LSTM's four gates (i, f, g, o) stack blocks of ``hidden_units`` rows.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np


def unit_groups(
    tensors: Mapping[str, np.ndarray], hidden_units: int, layers: int, directions: int = 1
) -> list[np.ndarray]:
    """Index arrays of the hidden units (ascending, the groups in order of their first
    unit) such that no weight connects units of two groups in any layer: the members of
    a merged model. One group of every unit for a bidirectional network (its backward
    direction reads every unit of the layer below) or one no zeros split."""
    h = hidden_units
    if directions != 1:
        return [np.arange(h)]
    coupled = np.zeros((h, h), dtype=bool)
    for k in range(layers):
        names = [f"lstm.weight_hh_l{k}"] + ([f"lstm.weight_ih_l{k}"] if k > 0 else [])
        for name in names:
            # Unit j's four gate rows against unit m's column.
            weights = np.asarray(tensors[name]).reshape(4, h, h)
            coupled |= np.any(weights != 0.0, axis=0)
    coupled |= coupled.T
    # Connected components by a plain search: scipy's csgraph would do it, but scipy is
    # not a dependency of this package nor of the estimator's pso_lstm back-end.
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


def gate_rows(hidden_units: int, units: np.ndarray) -> np.ndarray:
    """The rows of ``units`` in a gate-stacked weight or bias (i, f, g, o blocks)."""
    return np.concatenate([g * hidden_units + units for g in range(4)])


def member_tensors(
    tensors: Mapping[str, np.ndarray],
    hidden_units: int,
    layers: int,
    units: np.ndarray,
    *,
    head_bias: bool,
) -> dict[str, np.ndarray]:
    """The tensors of the network of ``units`` alone (a unidirectional lstm): their gate
    rows, their recurrent and upper-layer input columns, their head weights; the head's
    bias only where ``head_bias`` (exactly one group carries it), zeros else."""
    rows = gate_rows(hidden_units, units)
    out: dict[str, np.ndarray] = {}
    for k in range(layers):
        w_ih = np.asarray(tensors[f"lstm.weight_ih_l{k}"])[rows]
        out[f"lstm.weight_ih_l{k}"] = w_ih if k == 0 else w_ih[:, units]
        out[f"lstm.weight_hh_l{k}"] = np.asarray(tensors[f"lstm.weight_hh_l{k}"])[rows][:, units]
        for b in ("bias_ih", "bias_hh"):
            out[f"lstm.{b}_l{k}"] = np.asarray(tensors[f"lstm.{b}_l{k}"])[rows]
    out["head.weight"] = np.asarray(tensors["head.weight"])[:, units]
    bias = np.asarray(tensors["head.bias"])
    out["head.bias"] = bias if head_bias else np.zeros_like(bias)
    return {name: np.ascontiguousarray(t) for name, t in out.items()}


def joined_tensors(
    members: list[Mapping[str, np.ndarray]],
    groups: list[np.ndarray],
    hidden_units: int,
    layers: int,
) -> dict[str, np.ndarray]:
    """The inverse of :func:`member_tensors`: the wide network of ``hidden_units`` whose
    ``groups`` carry ``members``' tensors, zero between groups; the head's bias is the
    members' biases summed (the wide head adds what each member's head adds)."""
    h = hidden_units
    first = members[0]
    n_in = np.asarray(first["lstm.weight_ih_l0"]).shape[1]
    dtype = np.asarray(first["lstm.weight_hh_l0"]).dtype
    out: dict[str, np.ndarray] = {}
    for k in range(layers):
        out[f"lstm.weight_ih_l{k}"] = np.zeros((4 * h, n_in if k == 0 else h), dtype)
        out[f"lstm.weight_hh_l{k}"] = np.zeros((4 * h, h), dtype)
        out[f"lstm.bias_ih_l{k}"] = np.zeros(4 * h, dtype)
        out[f"lstm.bias_hh_l{k}"] = np.zeros(4 * h, dtype)
    out["head.weight"] = np.zeros((1, h), dtype)
    out["head.bias"] = np.zeros(1, dtype)
    for member, units in zip(members, groups, strict=True):
        rows = gate_rows(h, units)
        for k in range(layers):
            w_ih = np.asarray(member[f"lstm.weight_ih_l{k}"])
            if k == 0:
                out["lstm.weight_ih_l0"][rows] = w_ih
            else:
                out[f"lstm.weight_ih_l{k}"][np.ix_(rows, units)] = w_ih
            out[f"lstm.weight_hh_l{k}"][np.ix_(rows, units)] = member[f"lstm.weight_hh_l{k}"]
            for b in ("bias_ih", "bias_hh"):
                out[f"lstm.{b}_l{k}"][rows] = member[f"lstm.{b}_l{k}"]
        out["head.weight"][:, units] = member["head.weight"]
        out["head.bias"] += np.asarray(member["head.bias"])
    return out


__all__ = ["gate_rows", "joined_tensors", "member_tensors", "unit_groups"]
