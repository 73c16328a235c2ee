"""Several trained networks as one: the average of their β̂, written as a single LSTM.

Members that read the same inputs (features, prior, observer, window, step) but were
trained apart (other data, other car files, other seeds) err differently; the mean of
their estimates errs less than each (docs/training.md, "Two networks averaged"). The
average is exactly one wider LSTM: the members' hidden units side by side, every weight
that would connect two members zero (block-diagonal recurrent weights, and the input
weights of layers above the first), and one head that sums the members' heads, each
scaled by its share. So the merged file is an ordinary model artifact: the estimator,
its streaming engine and every tool run it unchanged, at the cost of the wider
network's arithmetic.

Each member's own normalisation is folded into its weights: the merged network z-scores
its inputs with the first member's statistics, and member *i*'s input weights and biases
are rewritten so that they see exactly what its own z-score would have given it,
``x_i = (s_0 / s_i) · x_0 + (m_0 − m_i) / s_i``. Likewise its head is rescaled from its
own ``beta_std``/``beta_mean`` to the merged ones. The merge is exact up to float32
rounding of the folded weights (checked in the tests against the members' mean).
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import replace
from datetime import UTC, datetime
from typing import Any

import numpy as np
import torch

from sideslip_msgs_py.artifact import ModelMetadata
from sideslip_msgs_py.data_source import RECORDINGS_KEY, recordings_in, total_recordings
from sideslip_msgs_py.fleet_envelope import EnvelopeError, FleetEnvelope

from .model import ModelConfig, SideslipNet

# What every member must share: the merged network reads one window and adds one prior.
SHARED = ("architecture", "layers", "features", "window_steps", "dt_s", "prior", "observer")


class MergeError(ValueError):
    """The members cannot be merged (named in the message)."""


def check_members(metas: Sequence[ModelMetadata], names: Sequence[str]) -> None:
    """Refuse members that differ in what the merged network must share, or a bilstm."""
    if len(metas) < 2:
        raise MergeError(f"merging needs at least two models, got {len(metas)}")
    first = metas[0]
    if first.architecture != "lstm":
        raise MergeError(f"{names[0]}: only lstm models merge, not {first.architecture}")
    for meta, name in zip(metas[1:], names[1:], strict=True):
        for field in SHARED:
            if getattr(meta, field) != getattr(first, field):
                raise MergeError(
                    f"{name}: its {field} ({getattr(meta, field)!r}) differs from "
                    f"{names[0]}'s ({getattr(first, field)!r}); members must share it"
                )


def merged_weights(
    nets: Sequence[SideslipNet], metas: Sequence[ModelMetadata], shares: Sequence[float]
) -> SideslipNet:
    """One LSTM whose output, z-scored with the first member's input statistics and its
    own β statistics (:func:`merged_metadata`), is Σ shareᵢ · β̂ᵢ of the members."""
    hidden = [m.hidden_units for m in metas]
    total, layers = sum(hidden), metas[0].layers
    out = SideslipNet(ModelConfig("lstm", len(metas[0].features), total, layers))
    m0, s0 = np.asarray(metas[0].feature_mean), np.asarray(metas[0].feature_std)
    beta_std = merged_beta(metas, shares)[1]
    # float64 while folding; the artifact stores float32 once, at the end.
    state = {k: torch.zeros_like(v, dtype=torch.float64) for k, v in out.state_dict().items()}
    starts = np.concatenate([[0], np.cumsum(hidden)])
    for net, meta, share, lo in zip(nets, metas, shares, starts[:-1], strict=True):
        h = meta.hidden_units
        own = {k: v.detach().to(torch.float64) for k, v in net.state_dict().items()}
        scale = torch.from_numpy(s0 / np.asarray(meta.feature_std))
        shift = torch.from_numpy(
            (m0 - np.asarray(meta.feature_mean)) / np.asarray(meta.feature_std)
        )
        for layer in range(layers):
            # The 4 gates (i, f, g, o) of each member are stacked blocks of h rows.
            for gate in range(4):
                rows = slice(gate * total + lo, gate * total + lo + h)
                own_rows = slice(gate * h, (gate + 1) * h)
                w_ih = own[f"lstm.weight_ih_l{layer}"][own_rows]
                b_ih = own[f"lstm.bias_ih_l{layer}"][own_rows]
                if layer == 0:
                    state["lstm.weight_ih_l0"][rows] = w_ih * scale
                    b_ih = b_ih + w_ih @ shift
                else:
                    state[f"lstm.weight_ih_l{layer}"][rows, lo : lo + h] = w_ih
                state[f"lstm.bias_ih_l{layer}"][rows] = b_ih
                state[f"lstm.bias_hh_l{layer}"][rows] = own[f"lstm.bias_hh_l{layer}"][own_rows]
                state[f"lstm.weight_hh_l{layer}"][rows, lo : lo + h] = own[
                    f"lstm.weight_hh_l{layer}"
                ][own_rows]
        gain = share * meta.beta_std / beta_std
        state["head.weight"][:, lo : lo + h] = own["head.weight"] * gain
        state["head.bias"] += own["head.bias"] * gain
    out.load_state_dict({k: v.to(torch.float32) for k, v in state.items()}, strict=True)
    return out.eval()


def merged_beta(metas: Sequence[ModelMetadata], shares: Sequence[float]) -> tuple[float, float]:
    """β mean and std [rad] of the merged output: the shares' mixture of the members'."""
    mean = float(sum(s * m.beta_mean for s, m in zip(shares, metas, strict=True)))
    std = float(sum(s * m.beta_std for s, m in zip(shares, metas, strict=True)))
    return mean, std


def merged_envelope(metas: Sequence[ModelMetadata]) -> dict[str, Any] | None:
    """The cars every member knows (the intersection of their envelopes): outside it one
    member would extrapolate, so the estimator treats the car as outside the fleet."""
    if any(m.envelope is None for m in metas):
        return None
    envs = [FleetEnvelope.from_dict(m.envelope) for m in metas if m.envelope is not None]
    bounds = {
        k: (max(e.bounds[k][0] for e in envs), min(e.bounds[k][1] for e in envs))
        for k in envs[0].bounds
    }
    try:
        return FleetEnvelope(bounds, min(e.cars for e in envs)).to_dict()
    except EnvelopeError as err:
        raise MergeError(f"the members' training cars do not overlap ({err})") from None


def merged_metadata(
    metas: Sequence[ModelMetadata], names: Sequence[str], shares: Sequence[float]
) -> ModelMetadata:
    """The merged network's metadata: the first member's inputs, the summed width, the
    mixed β statistics, the members' envelopes intersected; no σ and no metrics yet (the
    caller scores and calibrates on validation bags)."""
    beta_mean, beta_std = merged_beta(metas, shares)
    digest = hashlib.sha256("\n".join(m.training_data_digest for m in metas).encode()).hexdigest()
    members = [
        {
            "file": name,
            "share": float(share),
            "hidden_units": m.hidden_units,
            "training_data_digest": m.training_data_digest,
            "created_utc": m.created_utc,
            "command": m.provenance.get("command"),
            "val_mae_deg": m.metrics.get("val_mae_deg"),
        }
        for m, name, share in zip(metas, names, shares, strict=True)
    ]
    recordings = total_recordings(recordings_in(m.provenance) for m in metas)
    return replace(
        metas[0],
        hidden_units=sum(m.hidden_units for m in metas),
        beta_mean=beta_mean,
        beta_std=beta_std,
        training_data_digest=digest,
        metrics={},
        pso=None,
        provenance={
            "merged": members,
            **({} if recordings is None else {RECORDINGS_KEY: recordings}),
        },
        vehicle=metas[0].vehicle if all(m.vehicle == metas[0].vehicle for m in metas) else None,
        uncertainty=None,
        envelope=merged_envelope(metas),
        created_utc=datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
    )


def merge(
    members: Sequence[tuple[SideslipNet, ModelMetadata]],
    names: Sequence[str],
    shares: Sequence[float] | None = None,
) -> tuple[SideslipNet, ModelMetadata]:
    """The members as one network and its metadata (equal shares unless given; shares
    are positive and sum to 1)."""
    metas = [m for _, m in members]
    check_members(metas, names)
    shares = [1.0 / len(members)] * len(members) if shares is None else list(shares)
    if len(shares) != len(members) or any(not s > 0 for s in shares):
        raise MergeError(f"--shares needs one positive share per model, got {shares}")
    if abs(sum(shares) - 1.0) > 1e-9:
        raise MergeError(f"--shares must sum to 1, got {sum(shares):g}")
    net = merged_weights([n for n, _ in members], metas, shares)
    return net, merged_metadata(metas, names, shares)
