"""A trained :class:`~sideslip_training.model.SideslipNet` to and from its model artifact.

The artifact (:mod:`sideslip_msgs_py.artifact`) is the only thing the estimator sees:
float32 weights named as the network's ``state_dict`` plus the metadata (feature order,
normalisation, window, metrics). Loading rebuilds the network from the metadata alone.
"""

from __future__ import annotations

import os
from pathlib import Path

import torch

from sideslip_msgs_py.artifact import ArtifactError, ModelMetadata, read_artifact, write_artifact

from .model import ModelConfig, SideslipNet


def config_from_metadata(meta: ModelMetadata) -> ModelConfig:
    """The network shape an artifact's metadata describes."""
    return ModelConfig(
        architecture=meta.architecture,
        n_features=len(meta.features),
        hidden_units=meta.hidden_units,
        layers=meta.layers,
    )


def export_model(
    path: str | os.PathLike[str],
    model: SideslipNet,
    meta: ModelMetadata,
    force: bool = False,
) -> Path:
    """Write ``model``'s weights (as float32, on the CPU) and ``meta`` to ``path``.

    ``meta`` must describe ``model`` (architecture, hidden units, layers, number of
    features): :class:`ArtifactError` otherwise, as for an existing ``path`` without
    ``force``. Returns the path.
    """
    expected = config_from_metadata(meta)
    if model.config != expected:
        msg = f"{path}: the metadata describes {expected}, the model is {model.config}"
        raise ArtifactError(msg)
    tensors = {
        name: t.detach().to(device="cpu", dtype=torch.float32).contiguous().numpy()
        for name, t in model.state_dict().items()
    }
    return write_artifact(path, tensors, meta, force=force)


def load_model(path: str | os.PathLike[str]) -> tuple[SideslipNet, ModelMetadata]:
    """The network (eval mode, CPU, float32) and metadata of the artifact at ``path``.

    Raises :class:`ArtifactError` naming ``path`` for any file
    :func:`~sideslip_msgs_py.artifact.read_artifact` refuses.
    """
    tensors, meta = read_artifact(path)
    model = SideslipNet(config_from_metadata(meta))
    model.load_state_dict({name: torch.from_numpy(t) for name, t in tensors.items()}, strict=True)
    return model.eval(), meta
