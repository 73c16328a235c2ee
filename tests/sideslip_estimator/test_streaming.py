"""The streaming engine: on every window of a stream, the output of torch's LSTM/BiLSTM +
head run on that window alone from a zero state (float32 torch within 1e-6, float64 torch
to float64 rounding); reset restarts; the module imports no torch."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from streaming_support import (
    FLOAT64_ATOL,
    ROWS,
    SHIPPED,
    TORCH_FLOAT32_ATOL,
    TORCH_FLOAT32_RTOL,
    WINDOW,
    random_model,
    torch_outputs,
    z_rows,
)

from sideslip_estimator.backends.pso_lstm import PsoLstmBackend
from sideslip_estimator.streaming import KERNELS, StreamingLstm
from sideslip_msgs_py.artifact import (
    ArtifactError,
    denormalize_beta,
    read_artifact,
)
from sideslip_msgs_py.features import CHANNELS
from sideslip_msgs_py.model_inputs import columns_of_rows, input_matrix, prior_of_window

# --- the output of the per-window network on every window ---------------------------------------


@pytest.mark.parametrize(
    ("architecture", "layers", "hidden"),
    [
        ("lstm", 1, 8),
        ("lstm", 1, 40),
        ("lstm", 2, 16),
        ("bilstm", 1, 16),
        ("bilstm", 1, 33),
        ("bilstm", 2, 12),
    ],
)
def test_every_window_equals_torch_from_a_zero_state(
    tmp_path: Path, architecture: str, layers: int, hidden: int
) -> None:
    path = random_model(tmp_path / "m.safetensors", architecture, layers, hidden)
    tensors, meta = read_artifact(path)
    rows = z_rows(ROWS, len(meta.features))
    engine = StreamingLstm.from_artifact(path)
    y = engine.run(rows)
    assert y.shape == (ROWS - WINDOW + 1,)
    reference = torch_outputs(tensors, meta, rows, torch.float32)
    np.testing.assert_allclose(y, reference, rtol=0, atol=TORCH_FLOAT32_ATOL)
    # Exact: the float64 network on the same float32-rounded inputs, to float64 rounding.
    exact = torch_outputs(tensors, meta, rows, torch.float64)
    np.testing.assert_allclose(y, exact, rtol=0, atol=FLOAT64_ATOL)
    # float32 arithmetic: like torch's own rounding, not bit for bit.
    y32 = StreamingLstm.from_artifact(path, dtype=np.float32).run(rows)
    np.testing.assert_allclose(y32, reference, rtol=0, atol=TORCH_FLOAT32_ATOL)
    # The compiled fused kernel (float32, rational tanh): within torch's tolerance too.
    fused = StreamingLstm.from_artifact(path, kernel="numba").run(rows)
    np.testing.assert_allclose(fused, reference, rtol=0, atol=TORCH_FLOAT32_ATOL)


def test_a_short_window_fills_and_slides_like_a_long_one(tmp_path: Path) -> None:
    path = random_model(tmp_path / "m.safetensors", "lstm", 3, 8, window=7)
    tensors, meta = read_artifact(path)
    rows = z_rows(40, len(meta.features))
    np.testing.assert_allclose(
        StreamingLstm(tensors, meta).run(rows),
        torch_outputs(tensors, meta, rows, torch.float64),
        rtol=0,
        atol=FLOAT64_ATOL,
    )


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_shipped_models_equal_torch_on_every_window(path: Path) -> None:
    tensors, meta = read_artifact(path)
    rows = z_rows(meta.window_steps + 150, len(meta.features), seed=2)
    y = StreamingLstm.from_artifact(path).run(rows)
    reference = torch_outputs(tensors, meta, rows, torch.float32)
    np.testing.assert_allclose(y, reference, rtol=TORCH_FLOAT32_RTOL, atol=TORCH_FLOAT32_ATOL)
    exact = torch_outputs(tensors, meta, rows, torch.float64)
    np.testing.assert_allclose(y, exact, rtol=0, atol=FLOAT64_ATOL)
    fused = StreamingLstm.from_artifact(path, kernel="numba").run(rows)
    np.testing.assert_allclose(fused, reference, rtol=TORCH_FLOAT32_RTOL, atol=TORCH_FLOAT32_ATOL)


@pytest.mark.parametrize("name", ["pso_lstm_paper", "fleet_lstm_paper"])
def test_shipped_model_gives_the_pso_lstm_backends_beta(name: str) -> None:
    """From sensor rows: the back-end's β̂ (z-scoring, float32 rounding, torch, prior) is
    denormalize(push(z-scored row)) + prior on every window."""
    path = next(p for p in SHIPPED if p.stem == name)
    engine = StreamingLstm.from_artifact(path)
    meta = engine.meta
    # The network alone (its mirror average, the fleet models' default: test_mirror_average).
    values = {"model_file": str(path), "threads": 1, "mirror_average": False}
    backend = PsoLstmBackend(values, meta.window_steps)
    rng = np.random.default_rng(3)
    rows = rng.normal(0.0, 1.0, (meta.window_steps + 60, len(CHANNELS)))
    rows *= np.array([2.0, 0.5, 0.5, 4.0, 0.2, 0.02])
    rows[:, 0] += 20.0
    x = input_matrix(columns_of_rows(rows, meta.channels), meta.features)
    z = (x - np.asarray(meta.feature_mean)) / np.asarray(meta.feature_std)
    w, checked = meta.window_steps, 0
    for i, row in enumerate(z):
        y = engine.push(row)
        if i + 1 < w:
            assert y is None
            continue
        window = rows[i + 1 - w : i + 1]
        estimate = backend.update(window, np.arange(w, dtype=np.int64))
        prior = 0.0
        if meta.prior != "none":
            prior = prior_of_window(columns_of_rows(window, meta.channels), meta.prior, meta.dt_s)
        assert y is not None and estimate is not None
        beta = denormalize_beta(y, meta) + prior
        assert abs(beta - estimate.beta_rad) <= TORCH_FLOAT32_ATOL * meta.beta_std + 1e-12
        checked += 1
    assert checked == 61


# --- reset, faults, refusals --------------------------------------------------------------------


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize(("architecture", "layers"), [("lstm", 2), ("bilstm", 1), ("bilstm", 2)])
def test_reset_restarts_every_window(
    tmp_path: Path, architecture: str, layers: int, kernel: str
) -> None:
    path = random_model(tmp_path / "m.safetensors", architecture, layers, 8, window=20)
    engine = StreamingLstm.from_artifact(path, kernel=kernel)
    rows = z_rows(70, 6, seed=4)
    engine.run(rows[:33])
    engine.reset()
    assert engine.rows_pushed == 0
    assert all(engine.push(r) is None for r in rows[33:52])
    assert engine.push(rows[52]) is not None
    engine.reset()
    np.testing.assert_array_equal(
        engine.run(rows[33:]), StreamingLstm.from_artifact(path, kernel=kernel).run(rows[33:])
    )


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("bad", [np.nan, np.inf, 1e39])
def test_a_nan_row_gives_nan_for_exactly_the_windows_holding_it(
    tmp_path: Path, kernel: str, bad: float
) -> None:
    w = 10
    path = random_model(tmp_path / "m.safetensors", "lstm", 2, 8, window=w)
    rows = z_rows(40, 6, seed=5)
    clean = StreamingLstm.from_artifact(path, kernel=kernel).run(rows)
    rows[15, 2] = bad  # 1e39 overflows float32
    y = StreamingLstm.from_artifact(path, kernel=kernel).run(rows)
    # Window j holds rows j .. j + w − 1.
    holds = (np.arange(len(y)) <= 15) & (np.arange(len(y)) + w - 1 >= 15)
    assert np.isnan(y[holds]).all()
    np.testing.assert_array_equal(y[~holds], clean[~holds])


def test_a_row_of_the_wrong_length_is_refused(tmp_path: Path) -> None:
    engine = StreamingLstm.from_artifact(random_model(tmp_path / "m.safetensors", "lstm", 1, 4))
    with pytest.raises(ValueError, match=r"a row of 6 inputs, got shape \(5,\)"):
        engine.push(np.zeros(5))


def test_tensors_that_do_not_match_the_metadata_are_refused(tmp_path: Path) -> None:
    tensors, meta = read_artifact(random_model(tmp_path / "m.safetensors", "bilstm", 1, 4))
    with pytest.raises(ArtifactError, match=r"lstm\.weight_hh_l0_reverse is missing"):
        StreamingLstm({k: v for k, v in tensors.items() if "hh_l0_reverse" not in k}, meta)
    tensors["head.weight"] = np.zeros((1, 4), np.float32)
    with pytest.raises(ArtifactError, match=r"head\.weight has shape \(1, 4\), expected \(1, 8\)"):
        StreamingLstm(tensors, meta)
    with pytest.raises(ValueError, match="float64 or float32"):
        StreamingLstm(tensors, meta, dtype=np.float16)
    with pytest.raises(ValueError, match="kernel must be one of"):
        StreamingLstm(tensors, meta, kernel="cuda")


def test_the_module_does_not_import_torch() -> None:
    code = "import sideslip_estimator.streaming, sys; assert 'torch' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)
