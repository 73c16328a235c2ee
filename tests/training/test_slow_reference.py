"""A recording that starts at rest and reverses: β of a car below 1 m/s is no target.

atan2(v_y, v_x) of a car at rest is the angle of the reference's noise (up to ±180°);
training on it would swamp the loss and scoring it would swamp the metrics. The estimator
node publishes nothing below its ``min_speed_mps`` (1 m/s), so the data rule matches it.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sideslip_training.cli import train_main
from sideslip_training.dataset import MIN_REFERENCE_SPEED_MPS, load_runs, without_slow_targets

TINY = ["--profile", "quick", "--max-epochs", "2", "--device", "cpu", "--quiet"]


def _parked_then_driven(arrays, rng):
    """The first 1.5 s at rest (reference noise of 2 cm/s), then 0.5 s of reversing at
    2 m/s, then the drive as made."""
    v_x, v_y = arrays.truth_v_x_mps.copy(), arrays.truth_v_y_mps.copy()
    x_v = arrays.x_v_mps.copy()
    rest, back = 600, 800
    v_x[:rest], v_y[:rest] = rng.normal(0, 0.02, rest), rng.normal(0, 0.02, rest)
    v_x[rest:back], v_y[rest:back] = -2.0, rng.normal(0, 0.05, back - rest)
    x_v[:rest], x_v[rest:back] = 0.0, -2.0
    return dataclasses.replace(arrays, truth_v_x_mps=v_x, truth_v_y_mps=v_y, x_v_mps=x_v)


def test_a_recording_from_rest_trains_and_scores_only_where_the_car_moves(
    make_arrays, write_arrays, tmp_path: Path
) -> None:
    rng = np.random.default_rng(0)
    folder = tmp_path / "rec"
    for i in range(4):
        write_arrays(f"drive{i}", _parked_then_driven(make_arrays(4000, seed=i), rng), folder)
    runs, report = load_runs([folder])
    assert all(np.isnan(r.samples.beta_rad()[:800]).all() for r in runs)
    assert all(np.isfinite(r.samples.beta_rad()[800:]).all() for r in runs)
    assert any("800 sample(s) with the reference's forward speed under 1 m/s" in line
               for line in report.lines)  # fmt: skip

    out = tmp_path / "m.safetensors"
    # Whole bags to validation: the one it gets starts at rest too.
    args = ["--data", str(folder), "--model", "lstm", "--hidden-units", "4", "--split", "bag"]
    assert train_main([*args, "--out", str(out), *TINY]) == 0
    metrics = json.loads((tmp_path / "m.run" / "metrics.json").read_text())
    # At rest the reference's β is noise of ±180°: scored, it would put the MAE in tens
    # of degrees; without it the error is that of a drive with a |β| of a few degrees.
    assert math.isfinite(metrics["val_mae_deg"]) and metrics["val_mae_deg"] < 5.0


# make_arrays is a stateless factory: sharing it between examples is safe.
@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(speeds=st.lists(st.floats(-40.0, 60.0, allow_nan=False), min_size=1, max_size=50))
def test_beta_is_kept_exactly_where_the_reference_moves_forward_at_speed(speeds, make_arrays):
    base = make_arrays(len(speeds), seed=1)
    v_x = np.array(speeds)
    samples = dataclasses.replace(base, truth_v_x_mps=v_x)
    kept, count = without_slow_targets(samples)
    fast = v_x >= MIN_REFERENCE_SPEED_MPS
    assert count == int(np.count_nonzero(~fast))
    np.testing.assert_array_equal(kept.beta_rad()[fast], samples.beta_rad()[fast])
    assert np.isnan(kept.beta_rad()[~fast]).all()
    np.testing.assert_array_equal(kept.x_v_mps, samples.x_v_mps)


def test_a_recording_never_at_speed_is_refused_naming_the_rule(
    make_arrays, write_arrays, tmp_path: Path
) -> None:
    rng = np.random.default_rng(1)
    folder = tmp_path / "rec"
    write_arrays("drive", make_arrays(2000, seed=1), folder)
    parked = make_arrays(2000, seed=2)
    still = rng.normal(0, 0.02, 2000)
    write_arrays("parked", dataclasses.replace(parked, truth_v_x_mps=still), folder)
    runs, report = load_runs([folder])
    assert [r.bag for r in runs] == ["drive"]
    assert report.refused == ("parked: reference under 1 m/s throughout",)
