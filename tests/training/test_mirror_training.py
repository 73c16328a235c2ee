"""``sideslip-train --mirror``: every training run is also trained on mirrored left-right,
kept beside its original, while validation and test stay as recorded; by default only
when the training part is small."""

from __future__ import annotations

import json

import pytest

from sideslip_msgs_py.mirror import LATERAL_CHANNELS
from sideslip_training.cli import train_main
from sideslip_training.export import load_model

TINY = ["--profile", "quick", "--max-epochs", "2", "--device", "cpu", "--quiet"]


def _train_on_one_recording(make_arrays, write_arrays, tmp_path, *options: str) -> dict:  # type: ignore[no-untyped-def]
    """Train a tiny LSTM on one 10-s recording split in time; its config.json."""
    write_arrays("drive", make_arrays(4000, seed=3), folder=tmp_path / "rec")
    args = ["--data", str(tmp_path / "rec"), "--model", "lstm", "--hidden-units", "4"]
    args += ["--test-fraction", "0.3", *options]
    assert train_main([*args, "--out", str(tmp_path / "m.safetensors"), *TINY]) == 0
    return json.loads((tmp_path / "m.run" / "config.json").read_text())


def test_a_small_data_set_is_mirrored_by_default_training_runs_only(
    make_arrays, write_arrays, tmp_path
):
    config = _train_on_one_recording(
        make_arrays, write_arrays, tmp_path, "--features", "measurable"
    )
    assert config["train_bags"] == ["drive", "drive~mirror"]
    assert config["val_bags"] == ["drive@val"] and config["test_bags"] == ["drive@test"]
    # A run and its mirror image: the lateral inputs and β average to zero exactly.
    norm = config["normalizer"]
    for name, mean, std in zip(norm["features"], norm["mean"], norm["std"], strict=True):
        if name in LATERAL_CHANNELS:
            assert abs(mean) <= 1e-12 * std, name
    assert abs(norm["beta_mean"]) <= 1e-12 * norm["beta_std"]
    meta = load_model(tmp_path / "m.safetensors")[1]
    assert meta.beta_mean == pytest.approx(0.0, abs=1e-12)
    metrics = json.loads((tmp_path / "m.run" / "metrics.json").read_text())
    assert metrics["refit_epochs"] == metrics["best_epoch"]


def test_mirror_no_trains_on_the_recorded_runs_only(make_arrays, write_arrays, tmp_path):
    config = _train_on_one_recording(make_arrays, write_arrays, tmp_path, "--mirror", "no")
    assert config["train_bags"] == ["drive"]
    assert config["normalizer"]["beta_mean"] != pytest.approx(0.0, abs=1e-9)


def test_auto_mirrors_only_a_small_training_part() -> None:
    from sideslip_training.cli_errors import CliError
    from sideslip_training.training_data import wants_mirror

    assert wants_mirror("auto", 999_999, 10) and not wants_mirror("auto", 1_000_000, 10)
    assert not wants_mirror("auto", 300_000, 2)  # a profile with stride 2: 200 k is small
    assert wants_mirror("yes", 10**9, 10) and not wants_mirror("no", 10, 10)
    with pytest.raises(CliError, match="--mirror"):
        wants_mirror("maybe", 10, 10)


def test_mirror_val_validates_both_ways_and_the_refit_mirrors_each_run_once(
    make_arrays, write_arrays, tmp_path
):
    """``--mirror-val``: the validation part is judged on each run and its mirror image
    (a fleet drive opens its manoeuvres one way); the test part stays as recorded, and the
    refit on training + validation holds every mirror image exactly once."""
    from sideslip_training.dataset import Run
    from sideslip_training.training_data import TrainingData, with_mirrored

    config = _train_on_one_recording(
        make_arrays, write_arrays, tmp_path, "--mirror", "yes", "--mirror-val"
    )
    assert config["train_bags"] == ["drive", "drive~mirror"]
    assert config["val_bags"] == ["drive@val", "drive@val~mirror"]
    assert config["test_bags"] == ["drive@test"]
    assert config["args"]["mirror_val"] is True

    def run(name: str) -> Run:
        return Run(name=name, path=tmp_path / name, samples=make_arrays(300, seed=1))

    def refit_names(train: list[Run], val: list[Run], val_mirrored: bool) -> list[str]:
        data = TrainingData([], train, val, [], None, None, None, 1, "bag", True, val_mirrored)  # type: ignore[arg-type]
        return [r.name for r in data.refit_runs]

    train = with_mirrored([run("t")])
    assert refit_names(train, [run("v")], False) == ["t", "t~mirror", "v", "v~mirror"]
    assert refit_names(train, with_mirrored([run("v")]), True) == ["t", "t~mirror", "v", "v~mirror"]
