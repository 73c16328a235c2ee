"""SideslipNet: shapes, the last-step read-out of Fig. 5 (both directions for bilstm), seeding."""

from __future__ import annotations

import pytest
import torch

from sideslip_msgs_py.artifact import ModelMetadata, expected_tensors
from sideslip_msgs_py.features import CHANNELS
from sideslip_training.model import ModelConfig, SideslipNet

torch.set_num_threads(1)


@pytest.mark.parametrize("architecture", ["lstm", "bilstm"])
@pytest.mark.parametrize("layers", [1, 2])
def test_forward_maps_windows_to_one_beta_each(architecture: str, layers: int) -> None:
    net = SideslipNet(ModelConfig(architecture, n_features=5, hidden_units=8, layers=layers))
    out = net(torch.randn(3, 100, 5))
    assert out.shape == (3,)
    assert out.dtype == torch.float32


def test_parameter_names_and_shapes_are_the_artifacts() -> None:
    # The artifact names tensors after this module's state_dict: the contract.
    for architecture in ("lstm", "bilstm"):
        net = SideslipNet(ModelConfig(architecture, n_features=6, hidden_units=7, layers=2))
        meta = ModelMetadata(
            architecture=architecture,
            hidden_units=7,
            layers=2,
            features=CHANNELS,
            window_steps=100,
            dt_s=0.0025,
            feature_mean=(0.0,) * 6,
            feature_std=(1.0,) * 6,
            beta_mean=0.0,
            beta_std=1.0,
            training_data_digest="",
        )
        got = {k: tuple(v.shape) for k, v in net.state_dict().items()}
        assert list(got.items()) == list(expected_tensors(meta).items())


def test_lstm_output_depends_only_on_the_window_and_reads_the_last_step() -> None:
    torch.manual_seed(0)
    net = SideslipNet(ModelConfig("lstm", n_features=3, hidden_units=6)).eval()
    x = torch.randn(2, 20, 3)
    with torch.no_grad():
        out, _ = net.lstm(x)
        expected = net.head(out[:, -1, :]).squeeze(-1)
        torch.testing.assert_close(net(x), expected, rtol=0, atol=0)
        # Causal: the estimate at step T equals a run on the window alone, and changing
        # the last row changes it.
        y = x.clone()
        y[:, -1, :] += 1.0
        assert (net(y) != net(x)).all()


def test_bilstm_head_reads_both_directions_at_the_last_step() -> None:
    # MATLAB OutputMode 'last': forward state after the whole window, backward state at
    # the last step (which has seen only the last row).
    torch.manual_seed(1)
    h = 5
    net = SideslipNet(ModelConfig("bilstm", n_features=4, hidden_units=h)).eval()
    x = torch.randn(2, 30, 4)
    with torch.no_grad():
        fwd = torch.nn.LSTM(4, h, batch_first=True)
        bwd = torch.nn.LSTM(4, h, batch_first=True)
        for name in ("weight_ih_l0", "weight_hh_l0", "bias_ih_l0", "bias_hh_l0"):
            getattr(fwd, name).copy_(getattr(net.lstm, name))
            getattr(bwd, name).copy_(getattr(net.lstm, name + "_reverse"))
        h_fwd = fwd(x)[0][:, -1, :]  # after all 30 steps
        h_bwd = bwd(x[:, -1:, :])[0][:, 0, :]  # the backward pass has seen only row 30
        expected = net.head(torch.cat([h_fwd, h_bwd], dim=1)).squeeze(-1)
        torch.testing.assert_close(net(x), expected, rtol=1e-6, atol=1e-6)
        # Hence earlier rows reach the output only through the forward direction.
        y = x.clone()
        y[:, 0, :] += 1.0
        out_y, _ = net.lstm(y)
        out_x, _ = net.lstm(x)
        torch.testing.assert_close(out_y[:, -1, h:], out_x[:, -1, h:], rtol=0, atol=0)
        assert not torch.equal(out_y[:, -1, :h], out_x[:, -1, :h])


def test_the_same_seed_builds_the_same_network() -> None:
    cfg = ModelConfig("bilstm", n_features=6, hidden_units=8, layers=2)
    torch.manual_seed(42)
    a = SideslipNet(cfg)
    torch.manual_seed(42)
    b = SideslipNet(cfg)
    torch.manual_seed(43)
    c = SideslipNet(cfg)
    for (name, pa), pb in zip(a.state_dict().items(), b.state_dict().values(), strict=True):
        assert torch.equal(pa, pb), name
    assert not torch.equal(a.state_dict()["head.weight"], c.state_dict()["head.weight"])
    x = torch.randn(4, 100, 6)
    with torch.no_grad():
        assert torch.equal(a(x), b(x))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"architecture": "gru"}, "unknown architecture 'gru'"),
        ({"hidden_units": 0}, r"hidden_units must be an integer >= 1"),
        ({"layers": 1.0}, r"layers must be an integer >= 1"),
        ({"n_features": True}, r"n_features must be an integer >= 1"),
    ],
)
def test_invalid_config_is_refused(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        ModelConfig(**kwargs)
