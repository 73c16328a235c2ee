"""The trainer: seeded determinism, early stopping keeps the best epoch, and metrics."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from sideslip_training.evaluate import metrics_deg
from sideslip_training.trainer import TrainConfig, train_model


@pytest.fixture(scope="module")
def data(paper_windows):
    return paper_windows


def _cfg(**changes) -> TrainConfig:
    base = {"hidden_units": 8, "max_epochs": 3, "patience": 5, "batch_size": 32, "device": "cpu"}
    return TrainConfig(**(base | changes))


def test_same_seed_gives_the_same_weights_bit_for_bit_on_cpu(data):
    a = train_model(_cfg(seed=7), *data)
    b = train_model(_cfg(seed=7), *data)
    c = train_model(_cfg(seed=8), *data)
    for (name, wa), wb in zip(
        a.model.state_dict().items(), b.model.state_dict().values(), strict=True
    ):
        assert torch.equal(wa, wb), name
    assert any(
        not torch.equal(wa, wc)
        for wa, wc in zip(a.model.state_dict().values(), c.model.state_dict().values(), strict=True)
    )
    assert [r.val_mae_deg for r in a.history] == [r.val_mae_deg for r in b.history]


def test_early_stopping_keeps_the_best_epoch_weights(data):
    # A learning rate this high makes validation worse after a while: patience 1 stops
    # the run, and the weights returned must be the best epoch's, not the last one's.
    result = train_model(_cfg(learning_rate=0.3, max_epochs=12, patience=1, seed=1), *data)
    best = min(r.val_mae_deg for r in result.history)
    assert result.best_val_mae_deg == best
    assert result.history[result.best_epoch - 1].val_mae_deg == best
    from sideslip_training.trainer import mae_deg

    _train, val, norm = data
    again = mae_deg(
        result.model, val.to_torch(torch.device("cpu")), norm, torch.device("cpu"), len(val.ends)
    )
    assert again == pytest.approx(best, rel=1e-6)


def test_weight_averaging_keeps_the_averaged_weights_it_scored(data):
    from sideslip_training.trainer import mae_deg

    _train, val, norm = data
    cpu = torch.device("cpu")
    plain = train_model(_cfg(seed=3, max_epochs=4), *data)
    avg = train_model(_cfg(seed=3, max_epochs=4, average_weights=True), *data)
    again = train_model(_cfg(seed=3, max_epochs=4, average_weights=True), *data)
    # The same steps (same seed), but what is scored and returned is the average.
    assert [r.train_loss for r in avg.history] == [r.train_loss for r in plain.history]
    kept, last, rerun = (r.model.state_dict().values() for r in (avg, plain, again))
    assert any(not torch.equal(a, b) for a, b in zip(kept, last, strict=True))
    kept = avg.model.state_dict().values()
    assert all(torch.equal(a, b) for a, b in zip(kept, rerun, strict=True))
    scored = mae_deg(avg.model, val.to_torch(cpu), norm, cpu, len(val.ends))
    assert scored == pytest.approx(avg.best_val_mae_deg, rel=1e-6)
    assert avg.history[avg.best_epoch - 1].val_mae_deg == avg.best_val_mae_deg


@pytest.mark.parametrize("average", [False, True])
def test_fine_tuning_never_returns_a_model_worse_on_validation_than_its_start(data, average):
    from sideslip_training.trainer import mae_deg

    _train, val, norm = data
    cpu = torch.device("cpu")
    start = train_model(_cfg(seed=4, max_epochs=8), *data)
    state = {k: v.clone() for k, v in start.model.state_dict().items()}
    before = mae_deg(start.model, val.to_torch(cpu), norm, cpu, len(val.ends))
    # A step this large throws the trained weights away at every epoch.
    worse = train_model(
        _cfg(seed=4, learning_rate=5.0, patience=2, average_weights=average),
        *data,
        init_state=state,
    )
    assert worse.start_val_mae_deg == pytest.approx(before, rel=1e-6)
    assert all(r.val_mae_deg > before for r in worse.history)
    assert worse.best_epoch == 0 and worse.best_val_mae_deg == worse.start_val_mae_deg
    for name, w in worse.model.state_dict().items():
        assert torch.equal(w, state[name]), name
    # A gentle step that helps is kept as usual.
    better = train_model(_cfg(seed=4, learning_rate=1e-3, max_epochs=3), *data, init_state=state)
    if better.best_epoch:
        assert better.best_val_mae_deg < better.start_val_mae_deg


def test_a_run_that_never_yields_a_finite_epoch_is_an_error(data):
    with pytest.raises(ValueError, match="no epoch"):
        train_model(_cfg(learning_rate=1e30, max_epochs=2, seed=0), *data)


def test_metric_formulas_in_degrees():
    ref = np.radians([1.0, 2.0, 3.0, 4.0])
    est = np.radians([1.5, 2.0, 2.5, 5.0])
    m = metrics_deg(est, ref)
    err = np.array([0.5, 0.0, -0.5, 1.0])
    assert m.mae == pytest.approx(np.mean(np.abs(err)))
    assert m.me == pytest.approx(np.mean(err))
    assert m.rmse == pytest.approx(math.sqrt(np.mean(err**2)))
    assert m.r2 == pytest.approx(1 - np.sum(err**2) / np.sum((np.degrees(ref) - 2.5) ** 2))
    assert m.n == 4
    perfect = metrics_deg(ref, ref)
    assert perfect.mae == 0 and perfect.r2 == 1.0
