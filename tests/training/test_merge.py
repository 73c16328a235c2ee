"""sideslip-merge: several networks averaged, written as one wider LSTM that any reader runs."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py.artifact import ModelMetadata, read_artifact
from sideslip_msgs_py.fleet_envelope import QUANTITIES, FleetEnvelope
from sideslip_training.cli import train_main
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model
from sideslip_training.merge import MergeError, merge
from sideslip_training.merge_cli import main
from sideslip_training.model import ModelConfig, SideslipNet

FEATURES = ("x_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m")


def _member(hidden: int, layers: int, seed: int) -> tuple[SideslipNet, ModelMetadata]:
    """A network with random weights and its own (random) normalisation."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    net = SideslipNet(ModelConfig("lstm", len(FEATURES), hidden, layers)).eval()
    meta = ModelMetadata(
        architecture="lstm",
        hidden_units=hidden,
        layers=layers,
        features=FEATURES,
        window_steps=20,
        dt_s=0.0025,
        feature_mean=tuple(rng.normal(0.0, 2.0, len(FEATURES))),
        feature_std=tuple(rng.uniform(0.2, 5.0, len(FEATURES))),
        beta_mean=float(rng.normal(0.0, 1e-3)),
        beta_std=float(rng.uniform(1e-3, 2e-2)),
        training_data_digest=f"digest{seed}",
    )
    return net, meta


def _beta(net: SideslipNet, meta: ModelMetadata, raw: np.ndarray) -> np.ndarray:
    """β [rad] of raw (unnormalised) windows (B, T, F), as the estimator computes it."""
    x = (raw - np.asarray(meta.feature_mean)) / np.asarray(meta.feature_std)
    with torch.inference_mode():
        y = net(torch.from_numpy(x.astype(np.float32))).double().numpy()
    return y * meta.beta_std + meta.beta_mean


@settings(max_examples=12, deadline=None)
@given(
    hidden=st.lists(st.integers(1, 12), min_size=2, max_size=3),
    layers=st.integers(1, 2),
    weights=st.lists(st.floats(0.1, 1.0), min_size=3, max_size=3),
    seed=st.integers(0, 10_000),
)
def test_the_merged_network_gives_the_members_weighted_mean(
    hidden: list[int], layers: int, weights: list[float], seed: int
) -> None:
    members = [_member(h, layers, seed + i) for i, h in enumerate(hidden)]
    shares = np.asarray(weights[: len(hidden)]) / sum(weights[: len(hidden)])
    net, meta = merge(members, [f"m{i}" for i in range(len(hidden))], list(shares))
    assert meta.hidden_units == sum(hidden)
    raw = np.random.default_rng(seed).normal(1.0, 3.0, (7, 20, len(FEATURES)))
    expected = sum(s * _beta(n, m, raw) for s, (n, m) in zip(shares, members, strict=True))
    # float32 weights: agreement to a few 1e-6 of β's scale.
    scale = max(m.beta_std for _, m in members)
    np.testing.assert_allclose(_beta(net, meta, raw), expected, atol=5e-5 * scale)


def test_members_that_read_other_inputs_or_are_bidirectional_are_refused() -> None:
    a, b = _member(4, 1, 0), _member(4, 1, 1)
    with pytest.raises(MergeError, match="window_steps"):
        merge([a, (b[0], replace(b[1], window_steps=40))], ["a", "b"])
    with pytest.raises(MergeError, match="prior"):
        merge([a, (b[0], replace(b[1], prior="kinematic_window"))], ["a", "b"])
    with pytest.raises(MergeError, match="at least two"):
        merge([a], ["a"])
    with pytest.raises(MergeError, match="sum to 1"):
        merge([a, b], ["a", "b"], [0.5, 0.6])
    bi = SideslipNet(ModelConfig("bilstm", len(FEATURES), 4, 1))
    with pytest.raises(MergeError, match="only lstm"):
        merge([(bi, replace(a[1], architecture="bilstm")), b], ["a", "b"])


def _envelope(lo: float, hi: float) -> dict:
    return FleetEnvelope({k: (lo, hi) for k in QUANTITIES}, 3).to_dict()


def test_the_merged_model_knows_only_the_cars_every_member_knows() -> None:
    a, b = _member(4, 1, 0), _member(4, 1, 1)
    a = (a[0], replace(a[1], envelope=_envelope(1.0, 3.0)))
    b = (b[0], replace(b[1], envelope=_envelope(2.0, 4.0)))
    _, meta = merge([a, b], ["a", "b"])
    assert meta.envelope is not None
    bounds = FleetEnvelope.from_dict(meta.envelope).bounds
    assert all(pair == (2.0, 3.0) for pair in bounds.values())
    apart = (b[0], replace(b[1], envelope=_envelope(5.0, 6.0)))
    with pytest.raises(MergeError, match="do not overlap"):
        merge([a, apart], ["a", "b"])


def test_the_cli_merges_trained_models_scores_and_calibrates_them(
    sim_bag_dir: Path, tmp_path: Path, capsys
) -> None:
    """Two real trainings (other seeds) merged: the merged model's MAE is at most the
    members' mean (the mean's error is at most the mean error, sample by sample), it
    carries a σ, and sideslip-evaluate runs it as any model."""
    tiny = ["--profile", "quick", "--max-epochs", "2", "--device", "cpu", "--quiet"]
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "5"]
    models = []
    for seed in (1, 2):
        out = tmp_path / f"m{seed}.safetensors"
        assert train_main([*args, "--seed", str(seed), "--out", str(out), *tiny]) == 0
        models.append(str(out))
    merged = tmp_path / "merged.safetensors"
    assert main([*models, "--data", str(sim_bag_dir), "--out", str(merged)]) == 0
    _, meta = read_artifact(merged)
    assert meta.hidden_units == 10 and meta.uncertainty is not None
    members = meta.provenance["merged"]
    assert [m["file"] for m in members] == models
    assert meta.provenance["recordings"] == 0  # the members learnt from simulated bags
    assert meta.metrics["val_mae_deg"] <= np.mean([m["data_mae_deg"] for m in members]) + 1e-9
    assert "wrote" in capsys.readouterr().out
    # The merged file runs where a model runs: β̂ is the members' mean on a real bag.
    from sideslip_training.dataset import load_runs

    net, merged_meta = load_model(merged)
    run = load_runs([str(sim_bag_dir)], step_s=merged_meta.dt_s)[0][0]
    each = [predict_run(*load_model(m), run) for m in models]
    np.testing.assert_allclose(predict_run(net, merged_meta, run), np.mean(each, axis=0), atol=1e-7)
    # Scored and σ fitted on the estimate the node's default publishes: averaged with
    # its mirror image (simulated members); --mirror-average no scores the network alone.
    from sideslip_training.calibrate import Errors

    runs = load_runs([str(sim_bag_dir)], step_s=merged_meta.dt_s)[0]
    figures = merged_meta.metrics["interval_calibration"]
    assert figures["mirror_averaged"] == 1.0
    averaged = Errors.of_runs(runs, net, merged_meta, mirror_average=True)
    mae = float(np.degrees(np.mean(np.abs(averaged.err))))
    assert merged_meta.metrics["val_mae_deg"] == pytest.approx(mae, rel=1e-9)
    alone = tmp_path / "alone.safetensors"
    cmd = [*models, "--data", str(sim_bag_dir), "--out", str(alone), "--mirror-average", "no"]
    assert main(cmd) == 0
    alone_meta = read_artifact(alone)[1]
    assert alone_meta.metrics["interval_calibration"]["mirror_averaged"] == 0.0
    assert alone_meta.metrics["val_mae_deg"] != pytest.approx(mae, rel=1e-6)
    # Refusals: an existing --out without --force; a model that is not there.
    assert main([*models, "--data", str(sim_bag_dir), "--out", str(merged)]) == 2
    assert "--force" in capsys.readouterr().err
    code = main([models[0], str(tmp_path / "none.safetensors"), "--data", str(sim_bag_dir),
                 "--out", str(tmp_path / "x.safetensors")])  # fmt: skip
    assert code == 2 and "sideslip-merge: error" in capsys.readouterr().err


def test_described_car_files_alone_cannot_calibrate_the_merged_models_own_sigma(
    sim_bag_dir: Path, tmp_path: Path, capsys
) -> None:
    """The merged model's σ is the one published with true and identified files; one
    calibrated with guessed tyres alone is refused, naming the way to add it."""
    out = tmp_path / "m.safetensors"
    code = main(["fleet_ukf_measurable", "fleet_ukf_described", "--data", str(sim_bag_dir),
                 "--car", "described", "--out", str(out)])  # fmt: skip
    assert code == 2 and not out.exists()
    err = capsys.readouterr().err
    assert "made from a description" in err and "sideslip-calibrate --car described" in err
