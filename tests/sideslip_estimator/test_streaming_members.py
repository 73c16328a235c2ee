"""A merged model streamed member by member: the groups of units no weight connects are
found, each streams alone, and the sum is the wide network's output on every window."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from streaming_support import (
    FLOAT64_ATOL,
    SHIPPED,
    TORCH_FLOAT32_ATOL,
    TORCH_FLOAT32_RTOL,
    merged_random_net,
    random_model,
    torch_outputs,
    z_rows,
)

from sideslip_estimator.backends.torch_window import TorchWindow
from sideslip_estimator.streaming import KERNELS, StreamingLstm
from sideslip_estimator.streaming_members import MemberSum, streaming_engine, unit_groups
from sideslip_msgs_py.artifact import ModelMetadata, read_artifact

FEATURES = ("x_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m")
WINDOW = 20


def merged(
    hidden: list[int], layers: int, seed: int
) -> tuple[dict[str, np.ndarray], ModelMetadata]:
    """``sideslip-merge``'s network of random members of ``hidden`` units each."""
    net, meta = merged_random_net(hidden, layers, seed, FEATURES, WINDOW)
    tensors = {k: v.detach().numpy().copy() for k, v in net.state_dict().items()}
    return tensors, meta


@settings(max_examples=10, deadline=None)
@given(
    hidden=st.lists(st.integers(1, 9), min_size=2, max_size=4),
    layers=st.integers(1, 2),
    seed=st.integers(0, 10_000),
)
def test_a_merged_model_streams_per_member_and_equals_the_wide_network(
    hidden: list[int], layers: int, seed: int
) -> None:
    tensors, meta = merged(hidden, layers, seed)
    starts = np.cumsum([0, *hidden[:-1]])
    assert [g.tolist() for g in unit_groups(tensors, meta)] == [
        list(range(s, s + h)) for s, h in zip(starts, hidden, strict=True)
    ]
    rows = z_rows(WINDOW + 60, len(FEATURES), seed=seed)
    engine = streaming_engine(tensors, meta)
    assert isinstance(engine, MemberSum) and len(engine.engines) == len(hidden)
    y = engine.run(rows)
    np.testing.assert_allclose(y, StreamingLstm(tensors, meta).run(rows), rtol=0, atol=1e-12)
    exact = torch_outputs(tensors, meta, rows, torch.float64)
    np.testing.assert_allclose(y, exact, rtol=0, atol=FLOAT64_ATOL)
    fused = streaming_engine(tensors, meta, kernel="numba").run(rows)
    np.testing.assert_allclose(fused, exact, rtol=TORCH_FLOAT32_RTOL, atol=TORCH_FLOAT32_ATOL)


def test_a_weight_between_members_makes_the_model_one_group() -> None:
    """A fine-tuned merged model whose zeros filled in streams densely, not wrongly."""
    tensors, meta = merged([3, 4, 2], 1, seed=5)
    assert len(unit_groups(tensors, meta)) == 3
    tensors["lstm.weight_hh_l0"][2 * 9 + 8, 0] = 0.1  # gate g of unit 8 reads unit 0
    groups = unit_groups(tensors, meta)
    assert [g.tolist() for g in groups] == [[0, 1, 2, 7, 8], [3, 4, 5, 6]]
    rows = z_rows(WINDOW + 30, len(FEATURES))
    np.testing.assert_allclose(
        streaming_engine(tensors, meta).run(rows),
        torch_outputs(tensors, meta, rows, torch.float64),
        rtol=0,
        atol=FLOAT64_ATOL,
    )


@pytest.mark.parametrize(("architecture", "layers"), [("lstm", 1), ("lstm", 2), ("bilstm", 1)])
def test_a_network_no_zeros_split_streams_as_one(
    tmp_path: Path, architecture: str, layers: int
) -> None:
    tensors, meta = read_artifact(random_model(tmp_path / "m.safetensors", architecture, layers, 6))
    assert isinstance(streaming_engine(tensors, meta), StreamingLstm)


@pytest.mark.parametrize("kernel", KERNELS)
def test_nan_rows_and_reset_behave_as_in_one_engine(kernel: str) -> None:
    tensors, meta = merged([4, 5], 1, seed=3)
    rows = z_rows(WINDOW + 40, len(FEATURES))
    rows[WINDOW + 10, 2] = np.nan
    engine, dense = streaming_engine(tensors, meta, kernel=kernel), StreamingLstm(tensors, meta)
    got = [engine.push(r) for r in rows]
    want = [dense.push(r) for r in rows]
    assert [g is None for g in got] == [w is None for w in want]
    np.testing.assert_allclose(
        np.array([np.nan if g is None else g for g in got], dtype=float),
        np.array([np.nan if w is None else w for w in want], dtype=float),
        rtol=0,
        atol=1e-6,
    )
    assert engine.rows_pushed == len(rows)
    engine.reset()
    assert engine.rows_pushed == 0 and engine.push(rows[0]) is None


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_shipped_models_give_the_same_output_per_member(path: Path) -> None:
    tensors, meta = read_artifact(path)
    rows = z_rows(meta.window_steps + 50, len(meta.features), seed=4)
    engine = streaming_engine(tensors, meta)
    merged_file = "merged" in (meta.provenance or {})
    assert isinstance(engine, MemberSum) == merged_file
    np.testing.assert_allclose(
        engine.run(rows), StreamingLstm(tensors, meta).run(rows), rtol=0, atol=1e-12
    )


@pytest.mark.parametrize("layers", [1, 2])
def test_the_torch_engine_runs_a_merged_model_per_member_with_the_wide_networks_output(
    layers: int,
) -> None:
    tensors, meta = merged([4, 6, 3], layers, seed=8)
    window = TorchWindow(tensors, meta, threads=1)
    assert window.members == 3
    rows = z_rows(WINDOW + 5, len(FEATURES), seed=2)
    exact = torch_outputs(tensors, meta, rows, torch.float64)
    got = [window(rows[k : k + WINDOW]) for k in range(len(exact))]
    np.testing.assert_allclose(got, exact, rtol=TORCH_FLOAT32_RTOL, atol=TORCH_FLOAT32_ATOL)


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_the_torch_engine_splits_exactly_the_shipped_merged_models(path: Path) -> None:
    tensors, meta = read_artifact(path)
    window = TorchWindow(tensors, meta, threads=1)
    merged_members = len((meta.provenance or {}).get("merged", [])) or 1
    assert window.members == merged_members
    rows = z_rows(meta.window_steps, len(meta.features), seed=6)
    exact = torch_outputs(tensors, meta, rows, torch.float64)
    np.testing.assert_allclose(
        [window(rows)], exact, rtol=TORCH_FLOAT32_RTOL, atol=TORCH_FLOAT32_ATOL
    )
