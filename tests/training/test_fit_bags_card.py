"""The model card of sideslip-fit --bags: the separate recordings' table, its warning
when the fitted model's σ is too narrow for them and its note when σ is too wide."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import pytest

from sideslip_msgs_py.uncertainty import FitRange, Uncertainty
from sideslip_training.evaluate import Metrics
from sideslip_training.fit_bags_card import (
    GENTLE_MPS2,
    NARROW_SHARE,
    WIDE_SHARE,
    Scored,
    gentle_recordings,
    model_card,
    narrow_interval,
    wide_interval,
)

FITTED, SHIPPED = "LSTM (my_car)", "LSTM (fleet_ukf_measurable)"


def _scored(share: float) -> Scored:
    rows = {
        FITTED: Metrics(0.05, 0.0, 0.07, 0.99, 4000),
        SHIPPED: Metrics(0.06, 0.0, 0.08, 0.98, 4000),
        "β = 0": Metrics(0.7, 0.0, 0.9, -0.1, 4000),
    }
    return Scored(rows, {FITTED: share, SHIPPED: 0.97}, Path("report/test-bags.md"))


def _card(new_drives: Scored | None) -> str:
    args = argparse.Namespace(
        out=Path("my_car.safetensors"), vehicle=Path("my_car.yaml"), bags=["own/"],
        topic_map=None, features="measurable", profile="quick",
        test_bags=["other/"] if new_drives else None,
    )  # fmt: skip
    train = {"interval_calibration": {"scale_only": 1.0, "coverage_scale_half": 0.95}}
    return model_card(args, "recipe", 0.3, None, _scored(0.96), new_drives, train, 12.0)


@pytest.mark.parametrize("share", [0.5, NARROW_SHARE - 1e-6])
def test_a_narrow_sigma_on_the_separate_recordings_is_named_on_the_card(share):
    assert narrow_interval(_scored(share)) == share
    card = _card(_scored(share))
    assert f"**Only {share:.1%} of these samples lie inside the fitted model's ±1.96 σ" in card
    assert "--test-bags other/" in card


@pytest.mark.parametrize("share", [NARROW_SHARE, 0.95, WIDE_SHARE - 1e-6])
def test_a_sigma_that_holds_gets_no_warning(share):
    assert narrow_interval(_scored(share)) is None and wide_interval(_scored(share)) is None
    card = _card(_scored(share))
    assert "Result on the separate recordings" in card and "**Only" not in card
    assert "wider than a 95 % interval needs" not in card
    assert f"| {FITTED} | 0.0500 | 0.0700 | 0.990 | {share:.1%} | 4000 |" in card


@pytest.mark.parametrize("share", [WIDE_SHARE, 0.999, 1.0])
def test_a_wide_sigma_on_the_separate_recordings_is_noted_on_the_card(share):
    assert wide_interval(_scored(share)) == share and narrow_interval(_scored(share)) is None
    card = _card(_scored(share))
    assert f"{share:.1%} of these samples lie inside the fitted model's ±1.96 σ: on " in card
    assert "wider than a 95 % interval needs" in card and "**Only" not in card


def test_without_separate_recordings_the_card_asks_for_one():
    card = _card(None)
    assert "Result on the separate recordings" not in card
    assert "keep a separate recording for a final check (`--test-bags`" in card


def test_the_card_says_where_the_cars_sigma_holds_and_what_it_widens_to_beyond():
    args = argparse.Namespace(
        out=Path("my_car.safetensors"), vehicle=Path("my_car.yaml"), bags=["own/"],
        topic_map=None, features="measurable", profile="quick", test_bags=None,
    )  # fmt: skip
    train = {"interval_calibration": {"scale_only": 1.0, "coverage_scale_half": 0.95}}
    fit = FitRange(3.9, 0.14, 2.47, window_steps=100)
    unc = Uncertainty((1e-8, 2.7e-5, 1.2e-7, 4.8e-4), 0.8, fit_range=fit).to_dict()
    card = model_card(args, "recipe", 0.3, None, _scored(0.96), None, train, 12.0, unc)
    assert "(|a_y| ≤ 3.90 m/s², |β̇| ≤ 0.140 rad/s)" in card
    assert "the node publishes the shipped model's estimate and σ instead" in card
    assert "σ at scale 2.47 (2 × the shipped model's)" in card
    assert "|a_y| ≤" not in _card(None)
    # 3.9 m/s² is gentle driving: the card says what that means for the fitted model.
    assert "**The recordings stay under 3.9 m/s² of lateral acceleration.**" in card
    varied = Uncertainty((1e-8, 2.7e-5, 1.2e-7, 4.8e-4), 0.8, fit_range=replace(fit, **{
        "lateral_acceleration_mps2": GENTLE_MPS2}))  # fmt: skip
    assert gentle_recordings(varied.to_dict()) is None and gentle_recordings(unc) == 3.9
    card = model_card(args, "recipe", 0.3, None, _scored(0.96), None, train, 12.0,
                      varied.to_dict())  # fmt: skip
    assert "The recordings stay under" not in card
    # Not gentle: the node keeps this model's estimate beyond, σ widened.
    assert "the node publishes the shipped" not in card and "σ at scale 2.47" in card
