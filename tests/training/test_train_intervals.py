"""``sideslip-train --intervals``: a trained or fine-tuned model leaves with a calibrated
per-sample σ, fitted on validation data with the model early stopping chose."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sideslip_msgs_py.artifact import read_artifact
from sideslip_msgs_py.uncertainty import Uncertainty
from sideslip_training.cli import train_main
from sideslip_training.init_model import resolve

TINY = ["--profile", "quick", "--max-epochs", "2", "--device", "cpu", "--quiet"]


def _uncertainty(path: Path) -> Uncertainty | None:
    meta = read_artifact(path)[1]
    return None if meta.uncertainty is None else Uncertainty.from_dict(meta.uncertainty)


def test_fine_tuning_keeps_the_start_models_sigma_terms_and_refits_their_scale(
    make_arrays, write_arrays, tmp_path: Path
) -> None:
    # One recording split in time: validation is the stretch before the test, and the
    # exported model is refit on it, so σ comes from the model chosen before the refit.
    arrays = make_arrays(4000, seed=3)
    write_arrays("drive", arrays, folder=tmp_path / "rec")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--init", "fleet_lstm_paper"]
    assert train_main([*args, "--test-fraction", "0.3", "--out", str(out), *TINY]) == 0
    start = _uncertainty(resolve("fleet_lstm_paper"))
    mine = _uncertainty(out)
    assert start is not None and mine is not None
    assert mine.coefficients == start.coefficients and mine.scale != start.scale
    # Beyond the recordings' driving σ takes twice the start's scale when that is wider.
    fit = mine.fit_range
    assert fit is not None and fit.outside_scale == pytest.approx(2.0 * start.scale)
    assert fit.window_steps == read_artifact(out)[1].window_steps
    first_70 = np.abs(arrays.y_a_mps2[:2800])
    assert fit.lateral_acceleration_mps2 == pytest.approx(np.quantile(first_70, 0.999), rel=0.05)
    metrics = json.loads((tmp_path / "m.run" / "metrics.json").read_text())
    calibration = metrics["interval_calibration"]
    assert calibration["scale_only"] == 1.0 and calibration["fit_bags"] == 1.0
    assert calibration["coverage_scale_half"] == pytest.approx(0.95, abs=0.02)
    # The test part reports how often its β lies inside the published interval.
    fitted = next(v for k, v in metrics["test"].items() if k.startswith("LSTM"))
    assert 0.0 <= fitted["coverage_95"] <= 1.0
    assert "coverage_95" not in metrics["test"]["β = 0"]
    assert read_artifact(out)[1].metrics["interval_calibration"] == calibration


def test_a_model_from_scratch_fits_terms_and_scale_on_halves_of_the_validation_bags(
    sim_bag_dir: Path, tmp_path: Path
) -> None:
    out = tmp_path / "m.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "6"]
    assert train_main([*args, "--val-fraction", "0.5", "--out", str(out), *TINY]) == 0
    assert _uncertainty(out) is not None
    calibration = read_artifact(out)[1].metrics["interval_calibration"]
    assert calibration["scale_only"] == 0.0
    assert calibration["fit_bags"] == 1.0 and calibration["scale_bags"] == 1.0


def test_without_terms_to_keep_or_two_validation_bags_auto_gives_none_and_no_gives_none(
    sim_bag_dir: Path, tmp_path: Path
) -> None:
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "6", *TINY]
    assert train_main([*args, "--out", str(tmp_path / "auto.safetensors")]) == 0
    assert _uncertainty(tmp_path / "auto.safetensors") is None  # one validation bag
    fine = ["--data", str(sim_bag_dir), "--init", "fleet_lstm_paper", *TINY]
    assert train_main([*fine, "--intervals", "no", "--out", str(tmp_path / "no.safetensors")]) == 0
    assert _uncertainty(tmp_path / "no.safetensors") is None


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--model", "lstm", "--intervals", "scale"], "there is no --init"),
        (["--model", "lstm", "--intervals", "fit"], "two or more validation bags"),
    ],
)
def test_an_interval_policy_the_training_cannot_follow_is_refused_before_training(
    sim_bag_dir: Path, tmp_path: Path, capsys, extra: list[str], named: str
) -> None:
    out = tmp_path / "m.safetensors"
    assert train_main(["--data", str(sim_bag_dir), *extra, "--out", str(out), *TINY]) == 2
    err = capsys.readouterr().err
    assert named in err and len(err.strip().splitlines()) == 1
    assert not out.exists() and not (tmp_path / "m.run" / "history.json").exists()


def test_fine_tuning_with_described_car_files_rescales_the_starts_sigma_for_them(
    sim_bag_dir: Path, tmp_path: Path
) -> None:
    """A start that carries a σ for described car files (``fleet_ukf_ensemble``) keeps
    those terms where the runs read such files, and its own terms otherwise; the fitted
    model's one σ never carries the other beside its fit range."""
    start = _uncertainty(resolve("fleet_ukf_ensemble"))
    assert start is not None and start.described is not None
    args = ["--data", str(sim_bag_dir), "--init", "fleet_ukf_ensemble", *TINY]
    for car, terms in (("described", start.described), ("recorded", start)):
        out = tmp_path / f"{car}.safetensors"
        assert train_main([*args, "--car", car, "--out", str(out)]) == 0
        mine = _uncertainty(out)
        assert mine is not None and mine.described is None and mine.fit_range is not None
        assert mine.coefficients == terms.coefficients
        assert mine.fit_range.outside_scale == pytest.approx(2.0 * terms.scale)
