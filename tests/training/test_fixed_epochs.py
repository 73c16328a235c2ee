"""``sideslip-train --epochs N``: exactly N epochs, nothing chosen or kept back, then the
refit on all the bags; refused with anything that would choose or cap the count."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sideslip_training.cli import train_main

TINY = ["--profile", "quick", "--device", "cpu", "--quiet", "--mirror", "no"]


def test_a_fine_tune_given_epochs_trains_them_all_and_never_keeps_the_start(
    make_arrays, write_arrays, tmp_path: Path, capsys
) -> None:
    from sideslip_msgs_py.artifact import read_artifact
    from sideslip_training.init_model import resolve

    for i in range(4):
        write_arrays(f"drive{i}", make_arrays(1000, seed=i), folder=tmp_path / "rec")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--init", "fleet_lstm_paper", "--epochs", "3"]
    # Patience 1 would stop a chosen training after one epoch without a gain: not this one.
    assert train_main([*args, "--patience", "1", "--out", str(out), *TINY]) == 0
    assert "still improving" not in capsys.readouterr().err
    run = tmp_path / "m.run"
    history = json.loads((run / "history.json").read_text())
    metrics = json.loads((run / "metrics.json").read_text())
    assert history["epochs_run"] == history["best_epoch"] == 3
    assert metrics["fixed_epochs"] == metrics["best_epoch"] == metrics["refit_epochs"] == 3
    assert "kept_start_weights" not in metrics
    assert len(json.loads((run / "refit_history.json").read_text())) == 3
    start = read_artifact(resolve("fleet_lstm_paper"))[0]
    trained = read_artifact(out)[0]
    assert any(not np.array_equal(trained[k], start[k]) for k in start)


def test_given_epochs_without_a_refit_keep_the_training_parts_last_epoch(
    make_arrays, write_arrays, tmp_path: Path
) -> None:
    for i in range(4):
        write_arrays(f"drive{i}", make_arrays(800, seed=i), folder=tmp_path / "rec")
    args = ["--data", str(tmp_path / "rec"), "--model", "lstm", "--hidden-units", "4"]
    args += ["--epochs", "2", "--refit", "no"]
    assert train_main([*args, "--out", str(tmp_path / "m.safetensors"), *TINY]) == 0
    history = json.loads((tmp_path / "m.run" / "history.json").read_text())
    assert history["epochs_run"] == history["best_epoch"] == 2
    assert not (tmp_path / "m.run" / "refit_history.json").exists()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--epochs", "0"], "--epochs must be 1 or more, got 0"),
        (["--epochs", "3", "--folds", "2"], "--epochs 3 with --folds"),
        (["--epochs", "3", "--pso"], "--epochs 3 with --pso"),
        (["--epochs", "3", "--max-epochs", "5"], "--epochs 3 with --max-epochs"),
    ],
)
def test_epochs_with_what_would_choose_or_cap_them_is_refused_in_one_line(
    make_arrays, write_arrays, tmp_path: Path, capsys, extra: list[str], message: str
) -> None:
    for i in range(3):
        write_arrays(f"drive{i}", make_arrays(800, seed=i), folder=tmp_path / "rec")
    args = ["--data", str(tmp_path / "rec"), "--model", "lstm"]
    code = train_main([*args, *extra, "--out", str(tmp_path / "m.safetensors"), *TINY])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and message in err[-1] and err[-1].startswith("sideslip-train: error:")
    assert not (tmp_path / "m.safetensors").exists()
    assert not (tmp_path / "m.run").exists()
