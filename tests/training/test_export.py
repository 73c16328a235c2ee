"""export_model / load_model: the artifact rebuilds the same network, bit for bit."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch

from sideslip_msgs_py.artifact import (
    ArtifactError,
    ArtifactExistsError,
    ModelMetadata,
    read_artifact,
)
from sideslip_msgs_py.features import FEATURE_SETS
from sideslip_training.export import export_model, load_model
from sideslip_training.model import ModelConfig, SideslipNet

torch.set_num_threads(1)


def make_meta(net: SideslipNet, features: tuple[str, ...]) -> ModelMetadata:
    cfg = net.config
    return ModelMetadata(
        architecture=cfg.architecture,
        hidden_units=cfg.hidden_units,
        layers=cfg.layers,
        features=features,
        window_steps=100,
        dt_s=0.0025,
        feature_mean=tuple(0.5 * i for i in range(len(features))),
        feature_std=tuple(1.0 + i for i in range(len(features))),
        beta_mean=0.0,
        beta_std=0.03,
        training_data_digest="sha256:test",
        metrics={"val_rmse_deg": 0.25},
        provenance={"command": "pytest"},
    )


@pytest.mark.parametrize(
    ("architecture", "layers", "feature_set"),
    [("lstm", 1, "paper"), ("bilstm", 2, "measurable")],
)
def test_export_then_load_gives_the_same_outputs_bit_for_bit(
    tmp_path: Path, architecture: str, layers: int, feature_set: str
) -> None:
    features = FEATURE_SETS[feature_set]
    torch.manual_seed(3)
    net = SideslipNet(ModelConfig(architecture, len(features), 12, layers)).eval()
    meta = make_meta(net, features)
    path = export_model(tmp_path / "m.safetensors", net, meta)
    loaded, got_meta = load_model(path)
    assert got_meta == meta
    assert not loaded.training
    assert loaded.config == net.config
    for (name, a), b in zip(net.state_dict().items(), loaded.state_dict().values(), strict=True):
        assert torch.equal(a, b), name
    x = torch.randn(5, 100, len(features))
    with torch.inference_mode():
        assert torch.equal(net(x), loaded(x))
        assert torch.equal(net(x[:1]), loaded(x[:1]))


def test_export_writes_float32_from_a_float64_model(tmp_path: Path) -> None:
    net = SideslipNet(ModelConfig("lstm", 6, 4)).double()
    path = export_model(tmp_path / "m.safetensors", net, make_meta(net, FEATURE_SETS["paper"]))
    tensors, _ = read_artifact(path)
    assert {t.dtype for t in tensors.values()} == {np.dtype(np.float32)}


def test_export_refuses_metadata_that_does_not_describe_the_model(tmp_path: Path) -> None:
    net = SideslipNet(ModelConfig("lstm", 6, 4))
    meta = make_meta(net, FEATURE_SETS["paper"])
    for wrong in (
        dataclasses.replace(meta, architecture="bilstm"),
        dataclasses.replace(meta, hidden_units=5),
        dataclasses.replace(
            meta,
            features=FEATURE_SETS["measurable"],
            feature_mean=(0.0,) * 5,
            feature_std=(1.0,) * 5,
        ),
    ):
        with pytest.raises(ArtifactError, match=r"m\.safetensors: the metadata describes"):
            export_model(tmp_path / "m.safetensors", net, wrong)
    assert not (tmp_path / "m.safetensors").exists()


def test_export_refuses_to_overwrite_without_force(tmp_path: Path) -> None:
    net = SideslipNet(ModelConfig("lstm", 6, 4))
    meta = make_meta(net, FEATURE_SETS["paper"])
    path = export_model(tmp_path / "m.safetensors", net, meta)
    with pytest.raises(ArtifactExistsError):
        export_model(path, net, meta)
    export_model(path, net, meta, force=True)


def test_load_refuses_a_pickle_and_a_broken_file(tmp_path: Path) -> None:
    net = SideslipNet(ModelConfig("lstm", 6, 4))
    pickled = tmp_path / "state.pt"
    torch.save(net.state_dict(), pickled)  # the format we refuse: loading it runs code
    with pytest.raises(ArtifactError, match=r"state\.pt: not a safetensors file"):
        load_model(pickled)
    path = export_model(tmp_path / "m.safetensors", net, make_meta(net, FEATURE_SETS["paper"]))
    data = path.read_bytes()
    truncated = tmp_path / "truncated.safetensors"
    truncated.write_bytes(data[: len(data) - 10])
    with pytest.raises(ArtifactError, match=r"truncated\.safetensors: not a safetensors file"):
        load_model(truncated)
    with pytest.raises(ArtifactError, match=r"missing\.safetensors: no such file"):
        load_model(tmp_path / "missing.safetensors")
