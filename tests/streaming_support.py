"""Helpers of the streaming-engine tests: random model files, merged random networks,
z-scored rows, and torch's per-window output to compare with (imported by name:
``tests`` is on the path)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import torch
from numpy.lib.stride_tricks import sliding_window_view

from sideslip_msgs_py.artifact import ModelMetadata, expected_tensors, write_artifact
from sideslip_msgs_py.features import CHANNELS
from sideslip_training.merge import merge
from sideslip_training.model import ModelConfig, SideslipNet

torch.set_num_threads(1)
WINDOW = 100
ROWS = 300
TORCH_FLOAT32_ATOL = 1e-6
TORCH_FLOAT32_RTOL = 1e-6
"""Against torch's float32 network: its rounding, a few float32 ulps of the output (the
retrained fleet_ukf_measurable of 2026-12-02 differs by 1.05e-6 at an output of 1.45,
7e-7 of it); the float64 comparison beside it is the exact one."""
FLOAT64_ATOL = 1e-12
SHIPPED = sorted(
    Path(str(p))
    for p in resources.files("sideslip_estimator").joinpath("data/models").iterdir()
    if p.name.endswith(".safetensors")
)


def random_model(
    path: Path, architecture: str, layers: int, hidden: int, window: int = WINDOW, seed: int = 0
) -> Path:
    """An artifact of random weights (torch's init scale) for the paper's six channels."""
    meta = ModelMetadata(
        architecture=architecture,
        hidden_units=hidden,
        layers=layers,
        features=CHANNELS,
        window_steps=window,
        dt_s=0.0025,
        feature_mean=(20.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        feature_std=(5.0, 0.5, 0.5, 4.0, 0.2, 0.02),
        beta_mean=0.0,
        beta_std=0.03,
        training_data_digest="random",
    )
    rng = np.random.default_rng(seed)
    bound = 1.0 / np.sqrt(hidden)
    tensors = {
        name: rng.uniform(-bound, bound, shape).astype(np.float32)
        for name, shape in expected_tensors(meta).items()
    }
    return write_artifact(path, tensors, meta)


def z_rows(n: int, features: int, seed: int = 1) -> np.ndarray:
    """z-scored model inputs (float64), of order 1 with some outliers."""
    rng = np.random.default_rng(seed)
    return rng.normal(0.0, 1.0, (n, features)) * rng.choice([0.5, 1.0, 3.0], (1, features))


def torch_outputs(
    tensors: dict[str, np.ndarray], meta: ModelMetadata, rows: np.ndarray, dtype: torch.dtype
) -> np.ndarray:
    """y of every complete window of ``rows``: nn.LSTM + head on each window alone (zero
    initial state), the inputs rounded to float32 as the back-end does."""
    lstm = torch.nn.LSTM(
        len(meta.features),
        meta.hidden_units,
        num_layers=meta.layers,
        batch_first=True,
        bidirectional=meta.architecture == "bilstm",
    )
    weights = {k.removeprefix("lstm."): torch.from_numpy(v) for k, v in tensors.items()}
    lstm.load_state_dict({k: v for k, v in weights.items() if not k.startswith("head.")})
    lstm = lstm.to(dtype)
    windows = sliding_window_view(rows.astype(np.float32), (meta.window_steps, rows.shape[1]))
    # A copy: one window of a read-only view stays read-only, which torch warns about.
    x = torch.from_numpy(np.array(windows[:, 0])).to(dtype)
    head_w = torch.from_numpy(tensors["head.weight"]).to(dtype)
    head_b = torch.from_numpy(tensors["head.bias"]).to(dtype)
    with torch.inference_mode():
        output, _ = lstm(x)
        y = output[:, -1, :] @ head_w.T + head_b
    return y[:, 0].double().numpy()


def merged_random_net(
    hidden: list[int],
    layers: int,
    seed: int,
    features: tuple[str, ...],
    window: int,
    *,
    own_statistics: bool = False,
) -> tuple[SideslipNet, ModelMetadata]:
    """``sideslip-merge``'s network of random members of ``hidden`` units each; with
    ``own_statistics`` every member has its own input and β statistics, so the merge
    folds them into the weights (else unit input statistics, β mean 0)."""
    members = []
    for i, h in enumerate(hidden):
        torch.manual_seed(seed + i)
        net = SideslipNet(ModelConfig("lstm", len(features), h, layers)).eval()
        n = len(features)
        meta = ModelMetadata(
            architecture="lstm",
            hidden_units=h,
            layers=layers,
            features=features,
            window_steps=window,
            dt_s=0.0025,
            feature_mean=(
                tuple(0.1 * (i + 1) * k for k in range(n)) if own_statistics else (0.0,) * n
            ),
            feature_std=(1.0 + 0.2 * i,) * n if own_statistics else (1.0,) * n,
            beta_mean=0.001 * i if own_statistics else 0.0,
            beta_std=0.01 * (i + 1),
            training_data_digest=f"digest{i}",
        )
        members.append((net, meta))
    return merge(members, [f"m{i}" for i in range(len(hidden))])
