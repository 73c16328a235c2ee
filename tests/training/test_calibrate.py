"""sideslip-calibrate: a per-sample σ fitted on validation bags that covers what it says."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py.artifact import read_artifact
from sideslip_msgs_py.uncertainty import Uncertainty, terms
from sideslip_training.calibrate import (
    Errors,
    conformal_scale,
    coverage_of,
    fit_coefficients,
    main,
)
from sideslip_training.cli import train_main
from sideslip_training.evaluate_cli import main as evaluate_main

TORCH_ON_EVERY_CORE = True  # fits and scorings of shipped models (conftest)

TINY = ["--profile", "quick", "--max-epochs", "2", "--device", "cpu", "--quiet"]
TRUE = np.array([1e-8, 3e-4, 1e-7, 1e-4])


def _errors(n: int, seed: int, runs: int = 1) -> Errors:
    """Errors drawn from the model's own form with known coefficients."""
    rng = np.random.default_rng(seed)
    v = rng.uniform(3.0, 40.0, n)
    a_y = rng.normal(0.0, 4.0, n)
    r = a_y / v + rng.normal(0.0, 0.05, n)
    sigma = np.sqrt(terms(v, a_y, r) @ TRUE)
    run = rng.integers(0, runs, n)
    return Errors.from_arrays(rng.normal(0.0, 1.0, n) * sigma, v, a_y, r, run)


def test_the_fit_recovers_a_known_noise_model_and_the_scale_is_one() -> None:
    fit = np.array(fit_coefficients(_errors(40_000, 0)))
    # The dominant terms come back within 10 %; the scale then corrects nothing.
    np.testing.assert_allclose(fit[[1, 3]], TRUE[[1, 3]], rtol=0.1)
    assert conformal_scale(_errors(40_000, 1), fit, 0.95) == pytest.approx(1.0, abs=0.05)


@settings(max_examples=10, deadline=None)
@given(coverage=st.sampled_from([0.8, 0.9, 0.95, 0.99]), seed=st.integers(0, 1000))
def test_calibrated_intervals_hold_the_asked_share_of_fresh_samples(
    coverage: float, seed: int
) -> None:
    fit_on, scale_on, fresh = (_errors(20_000, seed + k) for k in range(3))
    coefficients = fit_coefficients(fit_on)
    unc = Uncertainty(coefficients, conformal_scale(scale_on, coefficients, coverage), coverage)
    pooled, _ = coverage_of(fresh, unc)
    assert pooled == pytest.approx(coverage, abs=0.01)


def test_the_cli_writes_the_model_with_its_uncertainty_and_evaluate_scores_it(
    sim_bag_dir: Path, tmp_path: Path, capsys
) -> None:
    model = tmp_path / "m.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "6"]
    assert train_main([*args, "--out", str(model), "--intervals", "no", *TINY]) == 0
    out = tmp_path / "calibrated.safetensors"
    assert main(["--model", str(model), "--data", str(sim_bag_dir), "--out", str(out)]) == 0
    before, after = read_artifact(model), read_artifact(out)
    assert after[1].uncertainty is not None and before[1].uncertainty is None
    for name, tensor in before[0].items():
        np.testing.assert_array_equal(after[0][name], tensor)  # the same network
    assert 0.9 < after[1].metrics["interval_calibration"]["coverage_scale_half"] <= 1.0
    assert "wrote" in capsys.readouterr().out
    # Trained on simulated bags alone: calibrated, as the node publishes it, on the network
    # averaged with its mirror image; --mirror-average no calibrates the network alone.
    assert after[1].metrics["interval_calibration"]["mirror_averaged"] == 1.0
    alone = tmp_path / "alone.safetensors"
    calibrate_alone = ["--model", str(model), "--data", str(sim_bag_dir), "--out", str(alone)]
    assert main([*calibrate_alone, "--mirror-average", "no"]) == 0
    alone_meta = read_artifact(alone)[1]
    assert alone_meta.metrics["interval_calibration"]["mirror_averaged"] == 0.0
    assert alone_meta.uncertainty != after[1].uncertainty
    capsys.readouterr()
    report = tmp_path / "report"
    assert (
        evaluate_main(["--model", str(out), "--data", str(sim_bag_dir), "--out", str(report)]) == 0
    )
    table = capsys.readouterr().out
    assert "inside the published 95 % interval" in table and "| pooled |" in table
    assert list(report.glob("band_*.png"))
    # Refusals: an existing --out without --force, a coverage that means nothing.
    assert main(["--model", str(model), "--data", str(sim_bag_dir), "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
    bad = ["--model", str(model), "--data", str(sim_bag_dir), "--out", str(tmp_path / "x")]
    assert main([*bad, "--coverage", "1.5"]) == 2


def test_scale_only_keeps_the_fleets_terms_and_sets_one_cars_error_level(
    foreign_bags, compact_rwd_description: Path, tmp_path: Path, capsys
) -> None:
    """One car's own recordings (another stack's bags, no car recorded) rescale the
    shipped measurable model's σ: same coefficients, another scale, and on those
    recordings the asked share inside."""
    from importlib import resources

    from sideslip_training.init_model import resolve

    folder, topic_map = foreign_bags
    ukf = resources.files("sideslip_estimator").joinpath("data/ukf/compact_rwd.yaml")
    out = tmp_path / "mine.safetensors"
    code = main(["--model", "fleet_ukf_measurable", "--data", str(folder), "--topic-map",
                 str(topic_map), "--vehicle", str(compact_rwd_description), "--observer-params",
                 str(ukf), "--car", "given", "--scale-only", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    shipped = Uncertainty.from_dict(read_artifact(resolve("fleet_ukf_measurable"))[1].uncertainty)
    _, meta = read_artifact(out)
    mine = Uncertainty.from_dict(meta.uncertainty)
    assert mine.coefficients == pytest.approx(shipped.coefficients, rel=1e-12)
    assert abs(mine.scale / shipped.scale - 1.0) > 0.05
    figures = meta.metrics["interval_calibration"]
    assert figures["scale_only"] == 1.0
    assert figures["coverage_scale_half"] == pytest.approx(0.95, abs=0.005)


def test_scale_only_needs_a_model_with_sigma_terms(sim_bag_dir: Path, tmp_path: Path, capsys):
    code = main(["--model", "pso_lstm_paper", "--data", str(sim_bag_dir), "--scale-only",
                 "--out", str(tmp_path / "x.safetensors")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert "--scale-only keeps the model's σ terms, but this model has none" in err
    assert err.splitlines()[-1].startswith("sideslip-calibrate: error:")


def test_car_given_without_files_is_refused(sim_bag_dir: Path, tmp_path: Path, capsys):
    code = main(["--model", "fleet_ukf_measurable", "--data", str(sim_bag_dir), "--car",
                 "given", "--out", str(tmp_path / "x.safetensors")])  # fmt: skip
    assert code == 2
    assert "--car given needs --vehicle and/or --observer-params" in capsys.readouterr().err


def test_a_fitted_models_range_survives_recalibration_and_its_flags_span_whole_runs(
    foreign_bags, compact_rwd_description: Path, tmp_path: Path, capsys
) -> None:
    """Calibrating a fine-tuned model again keeps where its σ holds; the errors it is
    scored on carry each sample's window flag from the whole run, as the node has it."""
    from dataclasses import replace
    from importlib import resources

    from sideslip_msgs_py.artifact import write_artifact
    from sideslip_msgs_py.topic_map import TopicMap
    from sideslip_msgs_py.uncertainty import FitRange
    from sideslip_msgs_py.vehicle_description import VehicleDescription
    from sideslip_training.dataset import load_runs
    from sideslip_training.export import load_model
    from sideslip_training.init_model import resolve

    folder, topic_map = foreign_bags
    ukf = resources.files("sideslip_estimator").joinpath("data/ukf/compact_rwd.yaml")
    tensors, meta = read_artifact(resolve("fleet_ukf_measurable"))
    fit = FitRange(2.0, 0.05, 2.5, window_steps=meta.window_steps)  # narrow: often left
    unc = replace(Uncertainty.from_dict(meta.uncertainty), fit_range=fit)
    fitted = tmp_path / "fitted.safetensors"
    write_artifact(fitted, tensors, replace(meta, uncertainty=unc.to_dict()))
    out = tmp_path / "again.safetensors"
    code = main(["--model", str(fitted), "--data", str(folder), "--topic-map", str(topic_map),
                 "--vehicle", str(compact_rwd_description), "--observer-params", str(ukf),
                 "--car", "given", "--scale-only", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert Uncertainty.from_dict(read_artifact(out)[1].uncertainty).fit_range == fit

    net, loaded = load_model(fitted)
    runs, _ = load_runs([folder], step_s=loaded.dt_s, topic_map=TopicMap.load(topic_map))
    vehicle = VehicleDescription.load(compact_rwd_description)
    car = {"vehicle": vehicle, "observer_params_file": str(ukf), "car": "given"}
    errors = Errors.of_runs(runs[:2], net, loaded, **car)
    assert errors.beyond is not None and 0.0 < errors.beyond.mean() < 1.0
    s = runs[0].samples
    whole = fit.window_beyond(s.x_v_mps, s.y_a_mps2, s.yaw_rate_radps)[loaded.window_steps - 1 :]
    first = errors.beyond[errors.run == 0]
    assert first.size == whole.size and (first == whole).all()


def test_errors_given_by_the_caller_calibrate_as_running_the_model_again(
    foreign_bags, compact_rwd_description: Path
) -> None:
    """sideslip-merge scores its model once and hands the errors to calibrate(): the
    runs' halves cut from them are what the model run on each half gives, window flags
    included, and so is the σ."""
    from dataclasses import replace
    from importlib import resources

    from sideslip_msgs_py.topic_map import TopicMap
    from sideslip_msgs_py.uncertainty import FitRange
    from sideslip_msgs_py.vehicle_description import VehicleDescription
    from sideslip_training.calibrate import calibrate
    from sideslip_training.dataset import load_runs
    from sideslip_training.export import load_model
    from sideslip_training.init_model import resolve

    folder, topic_map = foreign_bags
    ukf = resources.files("sideslip_estimator").joinpath("data/ukf/compact_rwd.yaml")
    net, meta = load_model(resolve("fleet_ukf_measurable"))
    fit = FitRange(2.0, 0.05, 2.5, window_steps=meta.window_steps)
    unc = replace(Uncertainty.from_dict(meta.uncertainty), fit_range=fit)
    meta = replace(meta, uncertainty=unc.to_dict())
    runs, _ = load_runs([folder], step_s=meta.dt_s, topic_map=TopicMap.load(topic_map))
    car = {
        "vehicle": VehicleDescription.load(compact_rwd_description),
        "observer_params_file": str(ukf),
        "car": "given",
    }
    errors = Errors.of_runs(runs, net, meta, **car)
    subset = [2, 0] if len(runs) > 2 else [1]
    alone = Errors.of_runs([runs[i] for i in subset], net, meta, **car)
    cut = errors.select(subset)
    for name in ("err", "v", "ay", "r", "run", "beyond"):
        np.testing.assert_array_equal(getattr(cut, name), getattr(alone, name), err_msg=name)
    assert calibrate(runs, net, meta, car=car, errors=errors) == calibrate(runs, net, meta, car=car)


def test_described_car_files_get_a_sigma_of_their_own_beside_the_models(
    foreign_bags, compact_rwd_description: Path, tmp_path: Path, capsys
) -> None:
    """Calibrated with the car file made from the car's description, the model keeps its
    σ for other files and gains one for described files; sideslip-evaluate publishes
    each with its kind of file, as the node does."""
    from dataclasses import replace
    from importlib import resources

    from sideslip_msgs_py.topic_map import TopicMap
    from sideslip_msgs_py.vehicle_description import VehicleDescription
    from sideslip_training.car_description import Description
    from sideslip_training.dataset import load_runs
    from sideslip_training.evaluate import evaluate_runs
    from sideslip_training.export import load_model
    from sideslip_training.init_model import resolve

    folder, topic_map = foreign_bags
    described = tmp_path / "described.ukf.yaml"
    described.write_text(Description.load(compact_rwd_description).ukf_params_yaml())
    given = ["--data", str(folder), "--topic-map", str(topic_map), "--vehicle",
             str(compact_rwd_description), "--car", "given", "--scale-only"]  # fmt: skip
    out = tmp_path / "mine.safetensors"
    code = main(["--model", "fleet_ukf_measurable", *given, "--observer-params", str(described),
                 "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert "σ for car files made from a description" in capsys.readouterr().err
    shipped = Uncertainty.from_dict(read_artifact(resolve("fleet_ukf_measurable"))[1].uncertainty)
    mine = Uncertainty.from_dict(read_artifact(out)[1].uncertainty)
    assert replace(mine, described=None) == shipped
    assert mine.described is not None and mine.described.scale != pytest.approx(shipped.scale)
    meta = read_artifact(out)[1]
    shipped_meta = read_artifact(resolve("fleet_ukf_measurable"))[1]
    assert meta.metrics["interval_calibration"] == shipped_meta.metrics["interval_calibration"]
    assert meta.metrics["interval_calibration_described"]["scale_only"] == 1.0
    assert meta.provenance["calibrated_described_on"] == [str(folder)]
    # Calibrating the model's own σ again keeps the one for described files.
    own = resources.files("sideslip_estimator").joinpath("data/ukf/compact_rwd.yaml")
    again = tmp_path / "again.safetensors"
    code = main(["--model", str(out), *given, "--observer-params", str(own), "--out",
                 str(again)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert Uncertainty.from_dict(read_artifact(again)[1].uncertainty).described == mine.described
    # Rescaling the σ for described files keeps its own terms, not the model's.
    terms_of_its_own = replace(
        mine, described=replace(mine.described, coefficients=(0, 1e-5, 1e-7, 0))
    )
    from sideslip_msgs_py.artifact import write_artifact

    tensors, meta = read_artifact(out)
    write_artifact(
        tmp_path / "own.safetensors", tensors, replace(meta, uncertainty=terms_of_its_own.to_dict())
    )
    rescaled = tmp_path / "rescaled.safetensors"
    code = main(["--model", str(tmp_path / "own.safetensors"), *given, "--observer-params",
                 str(described), "--out", str(rescaled)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    got = Uncertainty.from_dict(read_artifact(rescaled)[1].uncertainty).described
    assert got is not None and got.coefficients == (0, 1e-5, 1e-7, 0)

    net, meta = load_model(out)
    runs, _ = load_runs([folder], step_s=meta.dt_s, topic_map=TopicMap.load(topic_map))
    vehicle = VehicleDescription.load(compact_rwd_description)
    for ukf, unc in ((described, mine.described), (own, shipped)):
        files = {"vehicle": vehicle, "observer_params_file": str(ukf), "car": "given"}
        traces = evaluate_runs(
            runs[:1], [("m", net, meta)], window_steps=meta.window_steps, **files
        )
        (trace,) = (t for t in traces if t.estimator == "m")
        s = runs[0].samples
        want = np.sqrt(unc.variance(s.x_v_mps, s.y_a_mps2, s.yaw_rate_radps))
        np.testing.assert_allclose(trace.sigma_rad, want[meta.window_steps - 1 :], rtol=1e-12)


def test_a_mix_of_car_files_is_refused_where_the_model_keeps_a_sigma_for_each(
    sim_bag_dir: Path, tmp_path, capsys
):
    """``--car mixed`` gives half the bags their described car: one σ cannot be both of
    the ensemble's two."""
    from sideslip_training.observer import described_half

    halves = {described_half(p.name) for p in sim_bag_dir.iterdir() if p.is_dir()}
    assert halves == {True, False}  # the fixture's bags fall on both sides
    out = tmp_path / "x.safetensors"
    code = main(["--model", "fleet_ukf_ensemble", "--data", str(sim_bag_dir), "--car",
                 "mixed", "--out", str(out)])  # fmt: skip
    assert code == 2
    assert "mix described cars" in capsys.readouterr().err
    assert not out.exists()


def test_a_mix_of_car_files_calibrates_the_one_sigma_of_a_model_without_a_described_one(
    sim_bag_dir: Path, tmp_path, capsys
):
    """A model with one σ for every file (as ``fleet_ukf_described``, fitted at training
    on a mix) is calibrated on a mix the same way, and keeps no σ for described files."""
    out = tmp_path / "mixed.safetensors"
    code = main(["--model", "fleet_ukf_measurable", "--data", str(sim_bag_dir), "--car",
                 "mixed", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    meta = read_artifact(out)[1]
    unc = Uncertainty.from_dict(meta.uncertainty)
    assert unc.described is None
    assert "interval_calibration" in meta.metrics
    assert "interval_calibration_described" not in meta.metrics
    assert unc.scale > 0
    assert meta.provenance["calibrated_on"] == [str(sim_bag_dir)]
