"""``sideslip-train --mirror``: every training run is also trained on mirrored left-right,
kept beside its original, while validation and test stay as recorded."""

from __future__ import annotations

import json

import pytest

from sideslip_msgs_py.mirror import LATERAL_CHANNELS
from sideslip_training.cli import train_main
from sideslip_training.export import load_model

TINY = ["--profile", "quick", "--max-epochs", "2", "--device", "cpu", "--quiet"]


def test_mirror_adds_a_mirrored_copy_of_each_training_run_only(make_arrays, write_arrays, tmp_path):
    write_arrays("drive", make_arrays(4000, seed=3), folder=tmp_path / "rec")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--model", "lstm", "--hidden-units", "4"]
    args += ["--features", "measurable", "--test-fraction", "0.3", "--mirror"]
    assert train_main([*args, "--out", str(out), *TINY]) == 0
    config = json.loads((tmp_path / "m.run" / "config.json").read_text())
    assert config["train_bags"] == ["drive", "drive~mirror"]
    assert config["val_bags"] == ["drive@val"] and config["test_bags"] == ["drive@test"]
    # A run and its mirror image: the lateral inputs and β average to zero exactly.
    norm = config["normalizer"]
    for name, mean, std in zip(norm["features"], norm["mean"], norm["std"], strict=True):
        if name in LATERAL_CHANNELS:
            assert abs(mean) <= 1e-12 * std, name
    assert abs(norm["beta_mean"]) <= 1e-12 * norm["beta_std"]
    meta = load_model(out)[1]
    assert meta.beta_mean == pytest.approx(0.0, abs=1e-12)
    metrics = json.loads((tmp_path / "m.run" / "metrics.json").read_text())
    assert metrics["refit_epochs"] == metrics["best_epoch"]


def test_without_mirror_the_training_runs_are_the_recorded_ones(
    make_arrays, write_arrays, tmp_path
):
    write_arrays("drive", make_arrays(4000, seed=3), folder=tmp_path / "rec")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--model", "lstm", "--hidden-units", "4"]
    assert train_main([*args, "--test-fraction", "0.3", "--out", str(out), *TINY]) == 0
    config = json.loads((tmp_path / "m.run" / "config.json").read_text())
    assert config["train_bags"] == ["drive"]
    assert config["args"]["mirror"] is False
