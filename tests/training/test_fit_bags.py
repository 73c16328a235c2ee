"""sideslip-fit --bags: the car's own recordings (another stack's, 100 Hz) to a model."""

from __future__ import annotations

import argparse
import json
import shutil

import pytest

from sideslip_estimator.backends.ukf_model import UkfParams
from sideslip_msgs_py.artifact import read_artifact
from sideslip_training.evaluate import pooled
from sideslip_training.fit import main
from sideslip_training.fit_bags_args import DEFAULT_TEST_FRACTION
from sideslip_training.fit_bags_scoring import scored_traces
from sideslip_training.init_model import resolve

TORCH_ON_EVERY_CORE = True  # fits and scorings of shipped models (conftest)


@pytest.fixture(scope="module")
def fitted(foreign_bags, foreign_new_drives, tmp_path_factory):
    """One measurable fit on the foreign bags (2 epochs: a real, small training), with
    three other drives of the car as --test-bags."""
    from described_cars import describe_compact_rwd

    folder, topic_map = foreign_bags
    tmp = tmp_path_factory.mktemp("fit_bags")
    desc = describe_compact_rwd(tmp / "my_car.yaml")
    out = tmp / "my_car.safetensors"
    code = main(["--vehicle", str(desc), "--bags", str(folder), "--topic-map", str(topic_map),
                 "--features", "measurable", "--out", str(out), "--max-epochs", "2",
                 "--test-bags", str(foreign_new_drives), "--quiet"])  # fmt: skip
    return code, out


def _pooled(out) -> dict[str, float]:
    report = json.loads((out.with_suffix(".fit") / "report" / "metrics.json").read_text())
    return {r["estimator"]: r["mae"] for r in report["pooled"]}, report["models"]


def test_recordings_of_another_stack_give_a_model_its_axle_file_and_a_card(fitted):
    code, out = fitted
    assert code == 0
    assert out.exists()
    # The shipped start is scored on the validation stretch as the node runs it
    # (averaged with its mirror image: it learnt from simulated runs alone), the
    # fine-tuned network alone (it learnt from the 12 recordings). With the UKF observer
    # running through the cut into that stretch, as in the node, two epochs beat the
    # start there (until 2026-12-07 the observer started again at the cut, and the start
    # was kept): the file is the fine-tune, half way from the start's weights, records
    # its recordings, and the node runs it alone.
    metrics = json.loads((out.with_suffix(".fit") / "train-run" / "metrics.json").read_text())
    assert metrics["validation_mirror_averaged"] == {"start": True, "model": False}
    history = json.loads((out.with_suffix(".fit") / "train-run" / "history.json").read_text())
    assert min(r["val_mae_deg"] for r in history["history"]) < history["start_val_mae_deg"]
    assert "kept_start_weights" not in metrics
    assert read_artifact(out)[1].provenance["recordings"] == 12
    start = read_artifact(resolve("fleet_ukf_ensemble"))[0]
    assert any((tensor != start[name]).any() for name, tensor in read_artifact(out)[0].items())
    ukf = UkfParams.load(str(out.with_suffix(".ukf.yaml")))
    assert ukf.name == "my_car"
    card = out.with_suffix(".md").read_text()
    deploy = f"pso_lstm.observer_params_file:={out.with_suffix('.ukf.yaml')}"
    rows = ("UKF (described axles)", "UKF (identified axles)", "β = 0", "(my_car)")
    for text in (*rows, "(fleet_ukf_ensemble)", deploy):
        assert text in card
    assert "this file holds the shipped weights" not in card
    # The kinematic baselines read the reference velocity: not a sensor of this car.
    assert "Kinematic" not in card
    # Half way from the ensemble start's weights by default (what that does to the
    # weights: test_cli's interpolation test).
    config = json.loads((out.with_suffix(".fit") / "train-run" / "config.json").read_text())
    assert config["args"]["interpolate"] == 0.5


def test_the_identified_axles_and_the_fine_tuning_beat_what_the_node_had_before(
    fitted, foreign_bags
):
    """On the recordings' test part (never used to identify or train): compact_rwd's
    tyres are far from the fleet's typical ones its description implies, so the
    identified file must beat the described one clearly; the fine-tuned model must not
    be worse than the shipped one given the same file. (Whether the shipped network
    beats the UKF is no longer asserted: with the noise settings tuned on the fleet the
    UKF alone is the better on most cars; docs/training.md, "The UKF's noise on the
    fleet".)"""
    _, out = fitted
    mae, models = _pooled(out)
    assert mae["UKF (identified axles)"] < 0.6 * mae["UKF (described axles)"]
    # The card's rows are the node's defaults: the shipped start averaged with its mirror
    # image, the fitted network (it learnt from recordings) alone.
    assert mae[models["fitted"]] < mae[models["shipped"]]
    folder, topic_map = foreign_bags
    args = argparse.Namespace(topic_map=topic_map, vehicle=out.parent / "my_car.yaml")
    ukf = out.with_suffix(".ukf.yaml")
    traces, labels = scored_traces(
        args, [str(folder)], DEFAULT_TEST_FRACTION, [out], ukf, None, mirror_average=False
    )
    # The card scored the fit as the node runs it: alone.
    assert pooled(traces)[labels[0]].mae == pytest.approx(mae[models["fitted"]], rel=1e-9)


def test_the_fitted_model_publishes_a_calibrated_sigma_and_the_card_says_how_it_held(fitted):
    """σ terms kept from the shipped model, scale fitted on the validation stretch; the
    test part says how often β lay inside ±1.96 σ, for both models that carry σ."""
    from sideslip_msgs_py.artifact import read_artifact
    from sideslip_training.init_model import resolve

    _, out = fitted
    mine = read_artifact(out)[1]
    shipped = read_artifact(resolve("fleet_ukf_ensemble"))[1]
    assert mine.uncertainty is not None
    assert mine.uncertainty["coefficients"] == shipped.uncertainty["coefficients"]
    assert mine.metrics["interval_calibration"]["scale_only"] == 1.0
    report = json.loads((out.with_suffix(".fit") / "report" / "metrics.json").read_text())
    inside = {r["estimator"]: r.get("coverage_95") for r in report["pooled"]}
    models = report["models"]
    assert 0.5 < inside[models["fitted"]] <= 1.0 and 0.0 < inside[models["shipped"]] <= 1.0
    assert inside["β = 0"] is None
    card = out.with_suffix(".md").read_text()
    assert "inside ±1.96 σ" in card and f"{inside[models['fitted']]:.1%}" in card
    assert "fitted on the validation stretch" in card
    # Where that σ holds: the recordings' range, beyond it twice the shipped scale.
    fit = mine.uncertainty["fit_range"]
    assert fit["window_steps"] == mine.window_steps
    assert fit["outside_scale"] == pytest.approx(2.0 * shipped.uncertainty["scale"])
    assert f"|a_y| ≤ {fit['lateral_acceleration_mps2']:.2f} m/s²" in card
    gentle = fit["lateral_acceleration_mps2"] < 5.0
    assert ("The recordings stay under" in card) == gentle


def test_the_test_part_is_each_recordings_last_share(fitted, foreign_bags):
    """30 % of every recording by default: the test rows count that share of samples
    at the model's 400 Hz, less the first window of each."""
    _, out = fitted
    report = json.loads((out.with_suffix(".fit") / "report" / "metrics.json").read_text())
    assert report["test_fraction"] == 0.3
    table = (out.with_suffix(".fit") / "report" / "table.md").read_text()
    assert table.count("@test") >= 12


def test_separate_recordings_are_scored_whole_beside_the_test_part(
    fitted, foreign_bags, foreign_new_drives
):
    """--test-bags: every sample of the three other drives with a full window behind it
    (at the model's step), the same estimators as the test part, the share inside
    ±1.96 σ for the models with σ; on the card."""
    from sideslip_msgs_py.topic_map import TopicMap
    from sideslip_training.dataset import load_runs

    _, out = fitted
    report = json.loads((out.with_suffix(".fit") / "report" / "metrics.json").read_text())
    assert report["test_bags"] == [str(foreign_new_drives)]
    rows = {r["estimator"]: r for r in report["test_bags_pooled"]}
    assert set(rows) == {r["estimator"] for r in report["pooled"]}
    models = report["models"]
    assert 0.0 < rows[models["fitted"]]["coverage_95"] <= 1.0
    assert "coverage_95" not in rows["UKF (identified axles)"]
    runs, _ = load_runs(
        [foreign_new_drives], topic_map=TopicMap.load(foreign_bags[1]), step_s=0.0025
    )
    assert len(runs) == 3
    assert rows[models["fitted"]]["n"] == sum(len(r.samples) - 99 for r in runs)
    table = (out.with_suffix(".fit") / "report" / "test-bags.md").read_text()
    assert "@test" not in table
    card = out.with_suffix(".md").read_text()
    assert "Result on the separate recordings" in card
    assert f"| {models['fitted']} | {rows[models['fitted']]['mae']:.4f} |" in card
    assert f"--test-bags {foreign_new_drives}" in card
    # A measurable fit (axles identified) says its own test part flatters it.
    assert "compare both on a recording the fit never saw" in card


def test_paper_features_fine_tune_the_kinematic_residual_without_a_ukf_file(
    foreign_bags, compact_rwd_description, tmp_path, capsys
):
    """With two rehearsal runs: simulated cars like the described one train beside the
    recordings (read in our own topics, not through the map), and a second fit reuses
    them."""
    folder, topic_map = foreign_bags
    out = tmp_path / "paper.safetensors"
    args = ["--vehicle", str(compact_rwd_description), "--bags", str(folder),
            "--topic-map", str(topic_map), "--out", str(out), "--max-epochs", "1",
            "--test-fraction", "0.25", "--learning-rate", "0.0005", "--rehearse", "2"]  # fmt: skip
    assert main([*args, "--quiet"]) == 0, capsys.readouterr().err
    config = json.loads((tmp_path / "paper.fit" / "train-run" / "config.json").read_text())
    assert config["args"]["learning_rate"] == 0.0005 and config["args"]["test_fraction"] == 0.25
    assert config["args"]["interpolate"] == 0.5  # fleet_lstm_paper's share
    assert len(config["rehearsal_bags"]) == 2
    assert all("_rehearsal" in b for b in config["rehearsal_bags"])
    assert not any("_rehearsal" in b for b in config["val_bags"] + config["test_bags"])
    assert not out.with_suffix(".ukf.yaml").exists()
    card = out.with_suffix(".md").read_text()
    assert "(fleet_lstm_paper)" in card and "Kinematic (20-step mean)" in card
    assert "beside 2 simulated runs of cars like it" in card
    assert "UKF" not in card
    assert main([*args, "--force"]) == 0
    assert "rehearsal: 2 runs already simulated (reused)" in capsys.readouterr().err


def test_folds_choose_the_fine_tune_over_the_whole_part_before_the_test(
    foreign_bags, compact_rwd_description, tmp_path, capsys
):
    """--folds 2: each recording's part before its test cut into two blocks in time, the
    choice and σ made out of fold over both, recorded in the run folder and on the card."""
    folder, topic_map = foreign_bags
    out = tmp_path / "folds.safetensors"
    code = main(["--vehicle", str(compact_rwd_description), "--bags", str(folder),
                 "--topic-map", str(topic_map), "--out", str(out), "--max-epochs", "1",
                 "--folds", "2", "--quiet"])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    run = tmp_path / "folds.fit" / "train-run"
    assert json.loads((run / "config.json").read_text())["args"]["folds"] == 2
    cv = json.loads((run / "cross_validation.json").read_text())
    recordings = sum(1 for p in folder.iterdir() if p.is_dir())
    # Every recording gives each fold a block of its own (in time, not by bag).
    assert [f["fold"] for f in cv["per_fold"]] == [1, 2]
    assert all(f["val_runs"] >= recordings for f in cv["per_fold"]), cv["per_fold"]
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["cross_validation"]["folds"] == 2
    assert metrics["interval_calibration"]["out_of_fold_folds"] == 2
    card = out.with_suffix(".md").read_text()
    assert "2-fold cross-validation over the whole part" in card
    chosen = metrics["cross_validation"]["epochs"]
    said = f"{chosen} epoch{'s' * (chosen != 1)}, refit on all" if chosen else "keeping the start"
    assert said in card


def test_the_default_share_back_to_the_start_is_the_one_chosen_for_that_start(tmp_path):
    import argparse

    from sideslip_training.fit_bags_args import DEFAULT_INTERPOLATION, interpolation

    given = argparse.Namespace(interpolate=None)
    assert interpolation(given, "fleet_ukf_merged") == 0.25
    assert interpolation(given, "fleet_ukf_ensemble") == 0.5
    assert interpolation(given, str(tmp_path / "fleet_ukf_merged.safetensors")) == 0.25
    assert interpolation(given, "fleet_ukf_measurable") == DEFAULT_INTERPOLATION == 0.5
    assert interpolation(argparse.Namespace(interpolate=0.8), "fleet_ukf_merged") == 0.8


def test_the_ensemble_start_is_fine_tuned_at_its_own_learning_rate_unless_one_is_given(
    tmp_path,
):
    import argparse

    from sideslip_training.fit_bags_args import learning_rate

    given = argparse.Namespace(learning_rate=None)
    assert learning_rate(given, "fleet_ukf_ensemble") == 3e-4
    assert learning_rate(given, str(tmp_path / "fleet_ukf_ensemble.safetensors")) == 3e-4
    assert learning_rate(given, "fleet_ukf_merged") is None  # the profile's
    assert learning_rate(given, "fleet_lstm_paper") is None
    assert learning_rate(argparse.Namespace(learning_rate=1e-3), "fleet_ukf_ensemble") == 1e-3


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--test-fraction", "1.5"], "--test-fraction must be in (0, 1)"),
        (["--cars", "4"], "--cars is for simulated fits"),
        (["--rehearse", "-1"], "--rehearse must be >= 0 runs"),
        (["--folds", "0"], "--folds must be 1 (no cross-validation) or >= 2, got 0"),
        (["--interpolate", "1.5"], "--interpolate must be within (0, 1], got 1.5"),
        (["--test-bags", "{folder}"], "must be other drives than the fit's"),
        (["--test-bags", "{folder}/drive03"], "must be other drives than the fit's"),
        (["--test-bags", "{link}"], "must be other drives than the fit's"),
        (["--test-bags", "{tmp}/nothing"], "nothing"),
        (["--test-bags", "{short}"], "holds no stretch of a full 100-sample window"),
        (
            ["--features", "measurable", "--out", "{tmp}/fleet_ukf_ensemble.safetensors"],
            "name the fitted model other",
        ),
    ],
)
def test_options_that_do_not_fit_recordings_are_refused(
    foreign_bags, compact_rwd_description, tmp_path, capsys, extra, message
):
    """One line naming what is wrong, exit 2, before anything is trained."""
    folder, topic_map = foreign_bags
    out = tmp_path / "x.safetensors"
    (tmp_path / "link").symlink_to(folder / "drive05")  # the same drive under another name
    short = _short_recording(tmp_path / "short")
    paths = {"folder": folder, "tmp": tmp_path, "link": tmp_path / "link", "short": short}
    extra = [x.format(**paths) for x in extra]
    code = main(["--vehicle", str(compact_rwd_description), "--bags", str(folder), "--out",
                 str(out), "--topic-map", str(topic_map), *extra])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("sideslip-fit: error: ") and message in err and err.count("\n") == 1
    assert not out.exists()
    assert not list(tmp_path.glob("*.fit/train-run"))


def _short_recording(dest):
    """A 0.2-s recording (20 samples at 100 Hz: under a 250-ms window)."""
    from foreign_bag import make_truth, write_foreign_bag

    return write_foreign_bag(dest, make_truth(20))


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("--topic-map", "map.yaml"),
        ("--test-bags", "map.yaml"),
        ("--rehearse", "8"),
        ("--interpolate", "0.5"),
        ("--folds", "3"),
    ],
)
def test_recording_options_without_bags_are_refused(
    compact_rwd_description, tmp_path, capsys, option, value
):
    code = main(["--vehicle", str(compact_rwd_description), option, value,
                 "--out", str(tmp_path / "x.safetensors")])  # fmt: skip
    assert code == 2
    assert f"{option} needs --bags" in capsys.readouterr().err


@pytest.fixture
def one_recording(foreign_bags, tmp_path) -> tuple:
    """A folder with one of the foreign recordings (a few seconds), and the topic map."""
    folder, topic_map = foreign_bags
    bags = tmp_path / "bags"
    shutil.copytree(next(p for p in sorted(folder.iterdir()) if p.is_dir()), bags / "one")
    return bags, topic_map


def test_a_test_part_shorter_than_the_window_is_refused_before_training(
    one_recording, compact_rwd_description, tmp_path, capsys
):
    """One recording of a few seconds and 1 % for the test: no window fits in it."""
    bags, topic_map = one_recording
    out = tmp_path / "x.safetensors"
    code = main(["--vehicle", str(compact_rwd_description), "--bags", str(bags),
                 "--topic-map", str(topic_map), "--out", str(out), "--test-fraction", "0.01",
                 "--quiet"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2, err
    assert "shorter than the model's 0.25-s window" in err and err.count("\n") == 1
    assert not (tmp_path / "x.fit" / "train-run").exists()


def test_too_little_driving_to_identify_the_axles_is_refused(
    one_recording, compact_rwd_description, tmp_path, capsys
):
    bags, topic_map = one_recording
    out = tmp_path / "x.safetensors"
    code = main(["--vehicle", str(compact_rwd_description), "--bags", str(bags),
                 "--topic-map", str(topic_map), "--features", "measurable", "--out", str(out),
                 "--quiet"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2, err
    assert "usable points in 1 recording(s)" in err and err.count("\n") == 1
    assert not out.exists()
