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


def test_mirror_terms_mirror_the_raw_inputs_before_normalising(data):
    from sideslip_msgs_py.mirror import input_signs
    from sideslip_training.trainer import MirrorTerms

    _train, _val, norm = data
    terms = MirrorTerms.of(norm, torch.device("cpu"))
    raw = np.random.default_rng(3).normal(size=(50, len(norm.features))) * 4.0
    mean, std = np.asarray(norm.mean), np.asarray(norm.std)
    z = torch.as_tensor((raw - mean) / std, dtype=torch.float32)
    # As evaluate.predict_run and the node mirror: the raw inputs' signs, then z-scores.
    want = (raw * input_signs(norm.features) - mean) / std
    np.testing.assert_allclose((z * terms.scale + terms.shift).numpy(), want, atol=1e-5)
    # Mirroring twice gives the window back.
    twice = (z * terms.scale + terms.shift) * terms.scale + terms.shift
    np.testing.assert_allclose(twice.numpy(), z.numpy(), atol=1e-5)


def test_the_mirror_averaged_estimate_answers_the_mirrored_window_with_minus_beta(data):
    from sideslip_training.trainer import MirrorTerms

    _train, val, norm = data
    model = train_model(_cfg(seed=5, max_epochs=1), *data).model
    terms = MirrorTerms.of(norm, torch.device("cpu"))
    x, _y = val.to_torch(torch.device("cpu")).batch(torch.arange(min(64, len(val.ends))))
    with torch.inference_mode():
        here = terms.average(model, x) * norm.beta_std + norm.beta_mean
        there = terms.average(model, x * terms.scale + terms.shift) * norm.beta_std + norm.beta_mean
        alone = model(x) * norm.beta_std + norm.beta_mean
        alone_there = model(x * terms.scale + terms.shift) * norm.beta_std + norm.beta_mean
    np.testing.assert_allclose(there.numpy(), -here.numpy(), atol=1e-6)
    # The network alone is not odd (it never saw the mirrored windows as such).
    assert not np.allclose(alone_there.numpy(), -alone.numpy(), atol=1e-4)


def test_a_fine_tuning_scores_its_start_and_its_epochs_as_the_node_will_run_them(data):
    from sideslip_training.trainer import MirrorTerms, mae_deg

    _train, val, norm = data
    cpu = torch.device("cpu")
    start = train_model(_cfg(seed=6, max_epochs=2), *data)
    state = {k: v.clone() for k, v in start.model.state_dict().items()}
    val_t, n = val.to_torch(cpu), len(val.ends)
    terms = MirrorTerms.of(norm, cpu)
    alone = mae_deg(start.model, val_t, norm, cpu, n)
    averaged = mae_deg(start.model, val_t, norm, cpu, n, terms)
    assert averaged != pytest.approx(alone, rel=1e-4)
    # A start the node averages (it learnt from simulated runs) and a fine-tuned network
    # it runs alone (it learnt from recordings): the start is scored both ways, and an
    # epoch must beat the better of them, scored alone itself.
    tuned = train_model(
        _cfg(seed=6, learning_rate=1e-4, max_epochs=2),
        *data,
        init_state=state,
        deployed_mirror=(True, False),
    )
    forms = tuned.start_val_mae_forms
    assert forms["alone"] == pytest.approx(alone, rel=1e-6)
    assert forms["averaged"] == pytest.approx(averaged, rel=1e-6)
    assert tuned.start_val_mae_deg == min(forms.values())
    if tuned.best_epoch:
        kept = mae_deg(tuned.model, val_t, norm, cpu, n)
        assert kept == pytest.approx(tuned.best_val_mae_deg, rel=1e-6)
        assert kept < min(alone, averaged)
    # A start the node runs alone is scored alone only.
    plain = train_model(_cfg(seed=6, max_epochs=1), *data, init_state=state)
    assert plain.start_val_mae_forms == {"alone": pytest.approx(alone, rel=1e-6)}
    both = train_model(
        _cfg(seed=6, learning_rate=1e-4, max_epochs=1),
        *data,
        init_state=state,
        deployed_mirror=(True, True),
    )
    model = both.model if both.best_epoch else None
    if model is not None:
        scored = mae_deg(model, val_t, norm, cpu, n, terms)
        assert scored == pytest.approx(both.history[0].val_mae_deg, rel=1e-6)
