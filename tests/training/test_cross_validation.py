"""``sideslip-train --folds K``: the epoch count (and, fine-tuning, whether to keep the
start) chosen out of fold over every training and validation bag, not on one split."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sideslip_training.cli import train_main
from sideslip_training.cli_errors import CliError
from sideslip_training.cross_validation import (
    FoldRecord,
    choose_epochs,
    fold_runs,
    pooled_curve,
    pooled_start,
)
from sideslip_training.dataset import Run

TINY = ["--profile", "quick", "--device", "cpu", "--quiet", "--mirror", "no"]


def _runs(make_arrays, bags: list[str], per_bag: int = 1, n: int = 500) -> list[Run]:
    return [
        Run(name=f"{b}/{i}", path=Path(b), samples=make_arrays(n, seed=j), bag=b)
        for j, b in enumerate(bags)
        for i in range(per_bag)
    ]


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(bags=st.integers(3, 12), folds=st.integers(2, 6), seed=st.integers(0, 5))
def test_folds_by_bag_hold_every_bag_once_and_whole(
    make_arrays, bags: int, folds: int, seed: int
) -> None:
    names = [f"bag{i}" for i in range(bags)]
    runs = _runs(make_arrays, names, per_bag=2, n=50)
    if bags < folds:
        with pytest.raises(CliError, match=f"--folds {folds} needs at least {folds} bags"):
            fold_runs(runs, folds, "bag", seed)
        return
    groups = fold_runs(runs, folds, "bag", seed)
    assert len(groups) == folds and all(groups)
    assert sorted(r.name for g in groups for r in g) == sorted(r.name for r in runs)
    fold_of_bag = {r.bag: k for k, g in enumerate(groups) for r in g}
    assert all(fold_of_bag[r.bag] == k for k, g in enumerate(groups) for r in g)  # whole bags
    sizes = [len({r.bag for r in g}) for g in groups]
    assert max(sizes) - min(sizes) <= 1
    assert fold_runs(list(reversed(runs)), folds, "bag", seed)[0][0].bag in {
        r.bag for r in groups[0]
    }  # the input order does not move bags between folds


def test_folds_in_time_are_consecutive_blocks_that_cover_each_run(make_arrays) -> None:
    runs = _runs(make_arrays, ["long"], n=1003)
    groups = fold_runs(runs, 4, "time", 0)
    stamps = np.concatenate([g[0].samples.stamp_ns for g in groups])
    np.testing.assert_array_equal(stamps, runs[0].samples.stamp_ns)
    assert [g[0].name for g in groups] == [f"long/0#{k}" for k in range(4)]
    assert {len(g[0]) for g in groups} <= {250, 251}


def test_a_fold_that_stopped_early_counts_with_its_last_epoch() -> None:
    folds = [
        FoldRecord(1, 1, 100, 0.5, [0.4, 0.3, 0.35], 1.0),
        FoldRecord(2, 1, 300, 0.5, [0.6, 0.5, 0.45, 0.44, 0.6], 1.0),
    ]
    curve = pooled_curve(folds)
    assert curve == pytest.approx([0.55, 0.45, 0.425, 0.4175, 0.5375])
    assert choose_epochs(curve, start_mae_deg=0.5) == 4
    assert choose_epochs(curve, start_mae_deg=0.41) == 0  # no count beats the start
    assert choose_epochs(curve, start_mae_deg=None) == 4  # from scratch: some count


def test_fine_tuning_with_folds_chooses_out_of_fold_and_refits_on_all(
    make_arrays, write_arrays, tmp_path: Path
) -> None:
    for i in range(5):
        write_arrays(f"drive{i}", make_arrays(1200, seed=i), folder=tmp_path / "rec")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--init", "fleet_lstm_paper", "--folds", "3"]
    assert train_main([*args, "--max-epochs", "2", "--out", str(out), *TINY]) == 0
    cv = json.loads((tmp_path / "m.run" / "cross_validation.json").read_text())
    assert cv["folds"] == 3 and [f["fold"] for f in cv["per_fold"]] == [1, 2, 3]
    assert sum(f["val_runs"] for f in cv["per_fold"]) == 5  # every bag validated once
    assert all(f["start_mae_deg"] > 0 for f in cv["per_fold"])
    assert cv["start_pooled_mae_deg"] > 0 and 1 <= len(cv["pooled_curve_deg"]) <= 2
    metrics = json.loads((tmp_path / "m.run" / "metrics.json").read_text())
    assert metrics["cross_validation"]["epochs"] == cv["epochs"] == metrics["best_epoch"]
    if cv["epochs"]:
        assert metrics["refit_epochs"] == cv["epochs"]  # trained again on all five bags
    else:
        assert metrics["kept_start_weights"] is True


def _scratch_with_two_folds(make_arrays, write_arrays, tmp_path: Path) -> dict:
    """Train a tiny network from scratch with --folds 2 (no refit) on four drives; the
    cross-validation record."""
    for i in range(4):
        write_arrays(f"drive{i}", make_arrays(1000, seed=i), folder=tmp_path / "rec")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--model", "lstm", "--hidden-units", "4"]
    args += ["--folds", "2", "--max-epochs", "3", "--refit", "no"]
    assert train_main([*args, "--out", str(out), *TINY]) == 0
    return json.loads((tmp_path / "m.run" / "cross_validation.json").read_text())


def test_training_from_scratch_with_folds_trains_the_chosen_count(
    make_arrays, write_arrays, tmp_path: Path
) -> None:
    cv = _scratch_with_two_folds(make_arrays, write_arrays, tmp_path)
    history = json.loads((tmp_path / "m.run" / "history.json").read_text())
    assert cv["start_pooled_mae_deg"] is None and cv["epochs"] >= 1
    assert history["epochs_run"] == cv["epochs"] == history["best_epoch"]
    assert not (tmp_path / "m.run" / "refit_history.json").exists()


def test_each_folds_network_is_written_to_the_run_folder_at_its_best_epoch(
    make_arrays, write_arrays, tmp_path: Path
) -> None:
    from sideslip_msgs_py.artifact import read_artifact

    cv = _scratch_with_two_folds(make_arrays, write_arrays, tmp_path)
    final = read_artifact(tmp_path / "m.safetensors")[0]
    for fold in cv["per_fold"]:
        tensors, meta = read_artifact(
            tmp_path / "m.run" / "folds" / f"fold-{fold['fold']}.safetensors"
        )
        best = min(fold["epoch_mae_deg"])
        assert meta.metrics["fold"] == fold["fold"] and meta.metrics["folds"] == 2
        assert meta.metrics["val_mae_deg"] == pytest.approx(best)
        assert meta.metrics["best_epoch"] == 1 + fold["epoch_mae_deg"].index(best)
        assert meta.uncertainty is None and set(tensors) == set(final)
    assert sorted(p.name for p in (tmp_path / "m.run" / "folds").iterdir()) == [
        "fold-1.safetensors",
        "fold-2.safetensors",
    ]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--folds", "0"], "--folds must be 1 (the validation split) or >= 2, got 0"),
        (["--folds", "3", "--pso"], "not with --pso"),
        (["--folds", "4"], "--folds 4 needs at least 4 bags to deal out, got 3"),
    ],
)
def test_folds_that_cannot_be_cross_validated_are_refused_in_one_line(
    make_arrays, write_arrays, tmp_path: Path, capsys, extra: list[str], message: str
) -> None:
    for i in range(3):
        write_arrays(f"drive{i}", make_arrays(800, seed=i), folder=tmp_path / "rec")
    args = ["--data", str(tmp_path / "rec"), "--model", "lstm", "--split", "bag"]
    code = train_main([*args, *extra, "--out", str(tmp_path / "m.safetensors"), *TINY])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and message in err[-1] and err[-1].startswith("sideslip-train: error:")
    assert not (tmp_path / "m.safetensors").exists()


def test_when_no_epoch_count_beats_the_start_out_of_fold_the_start_is_exported(
    make_arrays, write_arrays, tmp_path: Path, capsys
) -> None:
    from sideslip_msgs_py.artifact import read_artifact
    from sideslip_training.init_model import resolve

    for i in range(4):
        write_arrays(f"drive{i}", make_arrays(1000, seed=i), folder=tmp_path / "rec")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--init", "fleet_lstm_paper", "--folds", "2"]
    args += ["--learning-rate", "3", "--max-epochs", "2"]  # a rate that only makes it worse
    assert train_main([*args, "--out", str(out), *TINY]) == 0
    assert "out of fold (2 folds, pooled)" in capsys.readouterr().err
    metrics = json.loads((tmp_path / "m.run" / "metrics.json").read_text())
    assert metrics["kept_start_weights"] is True and metrics["best_epoch"] == 0
    assert metrics["cross_validation"]["kept_start"] is True
    start = read_artifact(resolve("fleet_lstm_paper"))[0]
    kept = read_artifact(out)[0]
    assert all(np.array_equal(kept[k], start[k]) for k in start)


def test_the_starts_bar_pools_each_way_of_running_it_then_takes_the_better() -> None:
    """As the handover on one validation set: alone pooled, averaged pooled, the lower;
    not the better way per fold, a bar no single way of running the start reaches."""
    folds = [
        FoldRecord(1, 1, 100, 0.1, [0.2], 1.0, {"alone": 0.1, "averaged": 0.3}),
        FoldRecord(2, 1, 100, 0.1, [0.2], 1.0, {"alone": 0.3, "averaged": 0.1}),
    ]
    assert pooled_start(folds) == pytest.approx(0.2)
    assert pooled_start([FoldRecord(1, 1, 10, None, [0.2], 1.0)]) is None  # from scratch


def test_an_epoch_without_a_finite_pooled_mae_is_never_chosen() -> None:
    assert choose_epochs([float("nan"), 0.3, 0.2, float("nan")], None) == 3
    with pytest.raises(ValueError, match="diverged"):
        choose_epochs([float("nan")], 0.5)


def test_folds_in_time_over_one_recording_cross_validate_its_blocks(
    make_arrays, write_arrays, tmp_path: Path
) -> None:
    write_arrays("long", make_arrays(3000, seed=1), folder=tmp_path / "rec")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--model", "lstm", "--hidden-units", "4"]
    args += ["--folds", "3", "--max-epochs", "2", "--split", "time"]
    assert train_main([*args, "--out", str(out), *TINY]) == 0
    cv = json.loads((tmp_path / "m.run" / "cross_validation.json").read_text())
    # Each fold: a block of the training part and one of the validation part.
    assert [f["val_runs"] for f in cv["per_fold"]] == [2, 2, 2]


def test_folds_too_short_for_a_window_are_refused_before_anything_is_written(
    make_arrays, write_arrays, tmp_path: Path, capsys
) -> None:
    write_arrays("short", make_arrays(1000, seed=1), folder=tmp_path / "rec")
    args = ["--data", str(tmp_path / "rec"), "--model", "lstm", "--split", "time"]
    args += ["--folds", "20", "--out", str(tmp_path / "m.safetensors")]
    assert train_main([*args, *TINY]) == 2
    assert "fold 1 has no run of 100 samples" in capsys.readouterr().err
    assert not (tmp_path / "m.run").exists()
