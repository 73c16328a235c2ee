"""Beyond a fitted model's recordings (``beyond_fit_range``): ``sideslip-evaluate``
scores what the node publishes, the start model's estimate and σ while the window
reaches beyond the range the fine-tuning recorded, the fitted model's within."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sideslip_estimator.backends import create_backend
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_estimator.replay import replay, replay_columns
from sideslip_msgs_py.uncertainty import Uncertainty
from sideslip_training.cli import train_main
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import StartModelError, evaluate_runs, predict_run, start_of
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve

TINY = ["--profile", "quick", "--max-epochs", "1", "--device", "cpu", "--quiet"]


@pytest.fixture
def fitted_and_drive(make_arrays, write_arrays, tmp_path: Path) -> tuple[Path, Path]:  # type: ignore[no-untyped-def]
    """``fleet_lstm_paper`` fine-tuned on a gentle recording (|a_y| up to ~6 m/s²), and
    another drive of twice its lateral acceleration."""
    write_arrays("drive", make_arrays(4000, seed=3), folder=tmp_path / "rec")
    write_arrays("hard", make_arrays(2000, seed=5, v_x_mps=40.0), folder=tmp_path / "other")
    out = tmp_path / "fitted.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--init", "fleet_lstm_paper", "--test-fraction", "0.3"]
    assert train_main([*args, "--out", str(out), *TINY]) == 0
    return out, tmp_path / "other"


def test_evaluate_scores_the_start_model_beyond_the_recordings_as_the_node_publishes(
    fitted_and_drive: tuple[Path, Path],
) -> None:
    out, drives = fitted_and_drive
    net, meta = load_model(out)
    start_net, start_meta = load_model(resolve("fleet_lstm_paper"))
    run = load_runs([drives])[0][0]
    w = meta.window_steps
    # As the node's default mirror_average auto: the shipped start learnt from simulated
    # runs alone and is averaged with its mirror image, the model fitted to a recording
    # (its offsets kept) is not.
    assert meta.provenance["recordings"] == 1 and start_meta.provenance["recordings"] == 0
    traces = {
        mode: next(
            t
            for t in evaluate_runs(
                [run],
                [("fitted", net, meta)],
                window_steps=w,
                beyond_fit_range=mode,
                mirror_average="auto",
            )
            if t.estimator == "fitted"
        )
        for mode in ("start", "model", "auto")
    }
    fit = Uncertainty.from_dict(meta.uncertainty).fit_range
    assert fit is not None
    s = run.samples
    beyond = fit.window_beyond(s.x_v_mps, s.y_a_mps2, s.yaw_rate_radps)[w - 1 :]
    assert beyond.any() and (~beyond).any()
    own = predict_run(net, meta, run)
    start = predict_run(start_net, start_meta, run, mirror_average=True)
    assert np.nanmax(np.abs(start - predict_run(start_net, start_meta, run))) > 1e-5
    np.testing.assert_array_equal(traces["start"].estimate_rad, np.where(beyond, start, own))
    np.testing.assert_array_equal(traces["model"].estimate_rad, own)
    # Recordings up to ~6 m/s² are not gentle: auto keeps the fitted model's own.
    assert not fit.gentle
    np.testing.assert_array_equal(traces["auto"].estimate_rad, own)
    start_sigma = np.sqrt(
        Uncertainty.from_dict(start_meta.uncertainty).variance(
            s.x_v_mps, s.y_a_mps2, s.yaw_rate_radps
        )[w - 1 :]
    )
    assert traces["start"].sigma_rad is not None
    np.testing.assert_allclose(traces["start"].sigma_rad[beyond], start_sigma[beyond])
    # The node, sample by sample through the estimator, publishes the same.
    for mode in ("start", "auto"):
        backend = create_backend("pso_lstm", {"model_file": str(out), "beyond_fit_range": mode}, w)
        assert "averaged with its mirror image" not in backend.model_id.split(", beyond")[0]
        if mode == "start":
            assert "averaged with its mirror image" in backend._start.model_id
        node = replay(Estimator(backend, EstimatorParams(window_steps=w)), replay_columns(s))
        np.testing.assert_allclose(node.beta_rad[w - 1 :], traces[mode].estimate_rad, atol=1e-6)


def test_start_is_refused_when_no_model_records_a_range_and_for_unknown_modes(
    sim_bag_dir: Path,
) -> None:
    net, shipped = load_model(resolve("fleet_lstm_paper"))
    assert start_of(shipped, "auto", "shipped") is None
    assert start_of(shipped, "start", "shipped") is None  # beside a fitted model: scored as is
    run = load_runs([sim_bag_dir])[0][:1]
    with pytest.raises(StartModelError, match="no model records a range of recordings"):
        evaluate_runs(run, [("shipped", net, shipped)], window_steps=100, beyond_fit_range="start")
    with pytest.raises(StartModelError, match="beyond_fit_range must be one of"):
        start_of(shipped, "always", "shipped")
