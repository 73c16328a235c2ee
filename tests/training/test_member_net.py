"""Fine-tuning a merged model member by member: the split is exact, its gradients are the
wide network's, the weights between members stay zero, and the fine-tuned file still
streams per member; ``--init-members join`` lets the zeros fill in."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from streaming_support import merged_random_net

from sideslip_estimator.streaming import StreamingLstm
from sideslip_estimator.streaming_members import MemberSum, streaming_engine
from sideslip_msgs_py.artifact import ModelMetadata, read_artifact
from sideslip_msgs_py.model_members import joined_tensors, unit_groups
from sideslip_training.cli import train_main
from sideslip_training.config import WINDOW_STEPS
from sideslip_training.export import export_model, load_model
from sideslip_training.member_net import MemberNet, split_members
from sideslip_training.merge import merge
from sideslip_training.model import ModelConfig, SideslipNet
from sideslip_training.trainer import TrainConfig, train_model

FEATURES = ("x_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps")
N_FEATURES = len(FEATURES)
TINY = ["--profile", "quick", "--max-epochs", "2", "--device", "cpu", "--quiet"]


def merged_net(
    hidden: list[int], layers: int, seed: int, features: tuple[str, ...] = FEATURES
) -> tuple[SideslipNet, ModelMetadata]:
    """``sideslip-merge``'s network of random members, each with its own statistics."""
    return merged_random_net(hidden, layers, seed, features, WINDOW_STEPS, own_statistics=True)


def _state(net: torch.nn.Module) -> dict[str, np.ndarray]:
    return {k: v.detach().numpy().copy() for k, v in net.state_dict().items()}


@settings(max_examples=15, deadline=None)
@given(
    hidden=st.lists(st.integers(1, 7), min_size=2, max_size=4),
    layers=st.integers(1, 2),
    seed=st.integers(0, 10_000),
)
def test_a_merged_net_splits_into_its_members_and_joins_back_bit_for_bit(
    hidden: list[int], layers: int, seed: int
) -> None:
    wide, _ = merged_net(hidden, layers, seed)
    members = split_members(wide)
    assert isinstance(members, MemberNet)
    assert [len(g) for g in members.groups] == hidden
    for name, w in _state(members.joined()).items():
        np.testing.assert_array_equal(w, _state(wide)[name], err_msg=name)
    x = torch.randn(5, 12, N_FEATURES, generator=torch.Generator().manual_seed(seed))
    with torch.no_grad():
        torch.testing.assert_close(members(x), wide(x), rtol=1e-5, atol=1e-5)


def test_the_members_gradients_are_the_wide_networks_on_the_members_own_weights() -> None:
    """Training the members is training the wide network with the zeros frozen."""
    wide, _ = merged_net([3, 5, 2], 2, seed=11)
    wide = wide.double().train()
    members = split_members(wide)
    assert members is not None
    members = members.double()
    x = torch.randn(7, 15, N_FEATURES, dtype=torch.float64)
    y = torch.randn(7, dtype=torch.float64)
    for net in (wide, members):
        torch.nn.functional.mse_loss(net(x), y).backward()
    own = [
        {
            k: (np.zeros(p.shape) if p.grad is None else p.grad.numpy())
            for k, p in m.named_parameters()
        }
        for m in members.members
    ]
    # The members' gradients placed where their weights sit in the wide network, and
    # which entries are the members' own (ones placed the same way).
    placed = joined_tensors(own, members.groups, 10, 2)
    inside = joined_tensors(
        [{k: np.ones_like(g) for k, g in o.items()} for o in own], members.groups, 10, 2
    )
    for name, p in wide.named_parameters():
        mine = inside[name] != 0
        np.testing.assert_allclose(
            placed[name][mine], p.grad.numpy()[mine], rtol=1e-9, atol=1e-13, err_msg=name
        )
    assert not members.members[1].head.bias.requires_grad


def test_a_bilstm_or_a_plain_network_does_not_split() -> None:
    torch.manual_seed(0)
    assert split_members(SideslipNet(ModelConfig("lstm", N_FEATURES, 6, 1))) is None
    assert split_members(SideslipNet(ModelConfig("bilstm", N_FEATURES, 6, 1))) is None


@pytest.mark.parametrize("keep", [True, False])
def test_fine_tuning_a_merged_model_keeps_its_members_apart_unless_told_to_join(
    paper_windows, keep
):
    train, val, norm = paper_windows
    wide, _ = merged_net([4, 3], 1, seed=2, features=tuple(norm.features))
    cfg = TrainConfig(
        hidden_units=7, max_epochs=2, batch_size=32, device="cpu", seed=1, keep_members=keep
    )
    # A large step, so every trainable weight moves whatever the validation says.
    result = train_model(
        TrainConfig(**{**cfg.__dict__, "learning_rate": 0.05}),
        train,
        val,
        norm,
        init_state=wide.state_dict(),
        keep_last=True,
    )
    tuned, start = _state(result.model), _state(wide)
    assert isinstance(result.model, SideslipNet)
    assert not np.array_equal(tuned["lstm.weight_hh_l0"], start["lstm.weight_hh_l0"])
    groups = unit_groups(tuned, 7, 1)
    if keep:
        assert [g.tolist() for g in groups] == [[0, 1, 2, 3], [4, 5, 6]]
        zeros = start["lstm.weight_hh_l0"] == 0
        assert np.all(tuned["lstm.weight_hh_l0"][zeros] == 0)
    else:
        assert len(groups) == 1


def test_sideslip_train_init_of_a_merged_file_writes_one_that_streams_per_member(
    sim_bag_dir: Path, tmp_path: Path
) -> None:
    bases = []
    for seed in (1, 2):
        path = tmp_path / f"m{seed}.safetensors"
        args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "5"]
        assert train_main([*args, "--seed", str(seed), "--out", str(path), *TINY]) == 0
        bases.append(load_model(path))
    net, meta = merge(bases, ["m1", "m2"])
    start = export_model(tmp_path / "merged.safetensors", net, meta)
    runs = {}
    for members in ("keep", "join"):
        out = tmp_path / f"tuned-{members}.safetensors"
        args = ["--data", str(sim_bag_dir), "--init", str(start), "--init-members", members]
        assert train_main([*args, "--learning-rate", "0.01", "--out", str(out), *TINY]) == 0
        tensors, tuned_meta = read_artifact(out)
        runs[members] = streaming_engine(tensors, tuned_meta)
        assert tuned_meta.provenance["init_members"] == members
    assert isinstance(runs["keep"], MemberSum) and len(runs["keep"].engines) == 2
    assert isinstance(runs["join"], StreamingLstm)
