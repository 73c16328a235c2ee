"""σ after ``sideslip-train --folds K``: calibrated on every bag's out-of-fold errors (each
fold scored by the network that did not train on it), not on the validation split."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sideslip_training.calibrate import Errors
from sideslip_training.dataset import Run
from sideslip_training.fold_calibration import is_mirror_image
from sideslip_training.training_data import with_mirrored

TINY = ["--profile", "quick", "--device", "cpu", "--quiet", "--mirror", "no"]


def _errors(runs: int, per_run: list[int], seed: int) -> Errors:
    rng = np.random.default_rng(seed)
    n = sum(per_run)
    run = np.repeat(np.arange(runs), per_run)
    return Errors.from_arrays(*(rng.normal(size=n) for _ in range(4)), run=run)


@given(
    parts=st.lists(st.lists(st.integers(0, 5), min_size=1, max_size=4), min_size=1, max_size=4),
    seed=st.integers(0, 3),
)
def test_concatenated_errors_number_each_parts_runs_on_after_the_previous(
    parts: list[list[int]], seed: int
) -> None:
    """A run without a scored sample still takes its number: the numbers are positions
    in the runs' list, which calibrate() selects halves by."""
    made = [(_errors(len(p), p, seed + i), len(p)) for i, p in enumerate(parts)]
    joined = Errors.concatenate(made)
    assert len(joined) == sum(len(e) for e, _ in made)
    first = 0
    for errors, runs in made:
        own = joined.select(range(first, first + runs))
        assert np.array_equal(own.err, errors.err) and np.array_equal(own.run, errors.run)
        first += runs


def test_mirror_images_are_told_from_recorded_runs_also_as_blocks_in_time(make_arrays) -> None:
    run = Run(name="drive", path=Path("drive"), samples=make_arrays(200))
    recorded, mirror = with_mirrored([run])
    block = dataclasses.replace(mirror, name=mirror.name + "#2")
    assert not is_mirror_image(recorded) and not is_mirror_image(
        dataclasses.replace(run, name="drive#2")
    )
    assert is_mirror_image(mirror) and is_mirror_image(block)


@pytest.mark.parametrize("alpha", [1.0, 0.5])
def test_fine_tuning_with_folds_calibrates_on_every_bag_with_the_net_that_missed_it(
    make_arrays, write_arrays, tmp_path: Path, alpha: float
) -> None:
    """The exported σ's scale is the conformal scale of each fold's errors under the
    fold network written to the run folder (recomputed here from those files), moved
    toward the start as the exported model is with --interpolate."""
    from sideslip_msgs_py.data_source import mirror_average_on
    from sideslip_msgs_py.uncertainty import Uncertainty
    from sideslip_training.calibrate import conformal_scale
    from sideslip_training.cli import train_main
    from sideslip_training.cross_validation import fold_runs
    from sideslip_training.dataset import load_runs
    from sideslip_training.export import load_model
    from sideslip_training.init_model import resolve
    from sideslip_training.weight_interpolation import interpolate_toward

    for i in range(5):
        write_arrays(f"drive{i}", make_arrays(1200, seed=i), folder=tmp_path / "rec")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--init", "fleet_lstm_paper", "--folds", "3"]
    args += ["--interpolate", str(alpha), "--learning-rate", "1e-2"]
    assert train_main([*args, "--max-epochs", "2", "--out", str(out), *TINY]) == 0
    _, meta = load_model(out)
    figures = meta.metrics["interval_calibration"]
    assert figures["out_of_fold_folds"] == 3 and figures["scale_bags"] == 5
    start = Uncertainty.from_dict(load_model(resolve("fleet_lstm_paper"))[1].uncertainty)
    unc = Uncertainty.from_dict(meta.uncertainty)
    assert unc.coefficients == start.coefficients  # scale: the start's terms kept

    runs, _ = load_runs([tmp_path / "rec"])
    mirror = mirror_average_on("auto", meta.provenance)
    scoring = dataclasses.replace(meta, uncertainty=start.to_dict())
    parts = []
    start_net, _ = load_model(resolve("fleet_lstm_paper"))
    moved = 0
    for k, held in enumerate(fold_runs(runs, 3, "bag", 0)):
        net, fold = load_model(tmp_path / "m.run" / "folds" / f"fold-{k + 1}.safetensors")
        if fold.metrics["best_epoch"] > 0:
            interpolate_toward(net, start_net.state_dict(), alpha)
            moved += 1
        parts.append(Errors.of_runs(held, net, scoring, mirror_average=mirror))
    err = np.concatenate([p.err for p in parts])
    pooled = Errors.from_arrays(err, *(np.concatenate([getattr(p, a) for p in parts])
                                       for a in ("v", "ay", "r")))  # fmt: skip
    assert unc.scale == pytest.approx(conformal_scale(pooled, start.coefficients, 0.95), rel=1e-6)
    assert moved > 0  # a fold that trained, so that the interpolation is tested
    metrics = json.loads((tmp_path / "m.run" / "metrics.json").read_text())
    assert metrics["interval_calibration"]["out_of_fold_folds"] == 3
