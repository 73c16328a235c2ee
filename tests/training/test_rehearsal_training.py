"""``sideslip-train --rehearse``: other driving beside the user's recordings trains the
model, while validation, the test, the intervals' calibration and the recordings' range
(:class:`~sideslip_msgs_py.uncertainty.FitRange`) stay on the recordings."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sideslip_msgs_py.artifact import read_artifact
from sideslip_msgs_py.uncertainty import Uncertainty
from sideslip_training.cli import train_main

TINY = ["--profile", "quick", "--max-epochs", "2", "--device", "cpu", "--quiet"]


def test_rehearsal_trains_but_the_split_and_the_fit_range_stay_on_the_recordings(
    make_arrays, write_arrays, tmp_path: Path
) -> None:
    own = make_arrays(4000, seed=3)  # |a_y| up to about 6 m/s²
    write_arrays("drive", own, folder=tmp_path / "rec")
    hard = make_arrays(3000, seed=5, v_x_mps=40.0)  # twice the lateral acceleration
    write_arrays("hard", hard, folder=tmp_path / "sim")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--init", "fleet_lstm_paper", "--mirror", "no"]
    args += ["--rehearse", str(tmp_path / "sim"), "--test-fraction", "0.3"]
    assert train_main([*args, "--out", str(out), *TINY]) == 0
    config = json.loads((tmp_path / "m.run" / "config.json").read_text())
    assert config["train_bags"] == ["drive"] and config["rehearsal_bags"] == ["hard"]
    assert config["val_bags"] == ["drive@val"] and config["test_bags"] == ["drive@test"]
    fit = Uncertainty.from_dict(read_artifact(out)[1].uncertainty).fit_range
    assert fit is not None
    first_70 = np.abs(own.y_a_mps2[:2800])
    assert fit.lateral_acceleration_mps2 == pytest.approx(np.quantile(first_70, 0.999), rel=0.05)
    assert fit.lateral_acceleration_mps2 < 0.7 * np.quantile(np.abs(hard.y_a_mps2), 0.999)
    # The rehearsal is data: the training saw its windows (the data digest covers it).
    without = tmp_path / "without.safetensors"
    plain = [a for a in args if a not in ("--rehearse", str(tmp_path / "sim"))]
    assert train_main([*plain, "--out", str(without), *TINY]) == 0
    other = json.loads((tmp_path / "without.run" / "config.json").read_text())
    assert other["rehearsal_bags"] == [] and other["data_digest"] != config["data_digest"]


def test_a_rehearsal_bag_that_is_also_a_recording_is_refused(
    make_arrays, write_arrays, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    write_arrays("drive", make_arrays(4000, seed=3), folder=tmp_path / "rec")
    args = ["--data", str(tmp_path / "rec"), "--init", "fleet_lstm_paper"]
    args += ["--rehearse", str(tmp_path / "rec" / "drive"), "--test-fraction", "0.3"]
    assert train_main([*args, "--out", str(tmp_path / "m.safetensors"), *TINY]) != 0
    assert "--rehearse shares 1 bag(s)" in capsys.readouterr().err


def test_a_rehearsal_bag_without_its_car_is_refused_for_a_model_that_reads_the_car(
    make_arrays, write_arrays, compact_rwd_description, tmp_path: Path, capsys
) -> None:
    """Without a car record a rehearsal run would read the recordings' car: the
    corrections of another car, which rehearsal must not teach."""
    write_arrays("drive", make_arrays(4000, seed=3), folder=tmp_path / "rec")
    write_arrays("other", make_arrays(2000, seed=5), folder=tmp_path / "sim")
    args = ["--data", str(tmp_path / "rec"), "--model", "lstm", "--hidden-units", "4"]
    args += ["--features", "measurable_invariant", "--vehicle", str(compact_rwd_description)]
    args += ["--rehearse", str(tmp_path / "sim"), "--test-fraction", "0.3"]
    assert train_main([*args, "--out", str(tmp_path / "m.safetensors"), *TINY]) == 2
    assert "--rehearse: other records no car" in capsys.readouterr().err


def test_a_run_folder_from_before_rehearsal_resumes_as_one_without(tmp_path: Path) -> None:
    from sideslip_training.run_folder import RESUME_KEYS, start_run_folder

    config = {k: None for k in RESUME_KEYS} | {"rehearsal_bags": []}
    (tmp_path / "run").mkdir()
    old = {k: v for k, v in config.items() if k != "rehearsal_bags"}
    (tmp_path / "run" / "config.json").write_text(json.dumps(old))
    start_run_folder(tmp_path / "run", config, resume=True)  # no error
    with pytest.raises(Exception, match="rehearsal_bags"):
        start_run_folder(tmp_path / "run", config | {"rehearsal_bags": ["sim"]}, resume=True)
