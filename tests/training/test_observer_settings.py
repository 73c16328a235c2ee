"""``sideslip-train --observer-value``: a model anchored on the UKF can be trained on a
filter other than the back-end's defaults (e.g. with the lateral disturbance state); the
setting is stored in the model file and the node then runs that filter, answering as
offline scoring does. Bad settings are refused with exit 2, naming what is wrong."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sideslip_estimator.backends import create_backend
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_msgs_py.artifact import read_artifact
from sideslip_training import observer
from sideslip_training.cli import train_main
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model

from .test_cli import TINY, _feed
from .test_physics_models import car_files, train_ukf_residual


def test_a_model_trained_on_the_disturbance_filter_runs_it_in_the_node(
    sim_bag_dir: Path, tmp_path: Path
):
    plain, tilted = tmp_path / "plain.safetensors", tmp_path / "dist.safetensors"
    train_ukf_residual(sim_bag_dir, plain, "measurable_observer_signals")
    train_ukf_residual(
        sim_bag_dir,
        tilted,
        "measurable_observer_signals",
        "--observer-value",
        "estimate_disturbance=true",
        "--observer-value",
        "disturbance_memory_s=2.5",
    )
    assert read_artifact(plain)[1].observer["estimate_disturbance"] is False
    observer_values = read_artifact(tilted)[1].observer
    assert observer_values["estimate_disturbance"] is True
    assert observer_values["disturbance_memory_s"] == 2.5
    run = load_runs([sim_bag_dir])[0][0]
    car, params = car_files(run.run_metadata["vehicle"], tmp_path)
    net, meta = load_model(tilted)
    # As the node's default: trained on simulated bags, averaged with its mirror image.
    offline = predict_run(net, meta, run, mirror_average="auto")
    values = {"model_file": str(tilted), "observer_params_file": str(params),
              "vehicle_file": str(car)}  # fmt: skip
    backend = create_backend("pso_lstm", values, meta.window_steps)
    est = Estimator(backend, EstimatorParams(window_steps=meta.window_steps, max_gap_s=1.0))
    np.testing.assert_allclose(_feed(est, run.samples), offline, rtol=0, atol=1e-6)
    # Not the default filter: the observer columns the network reads differ on the run.
    plain_columns = observer.columns(run, read_artifact(plain)[1].observer)
    tilted_columns = observer.columns(run, observer_values)
    assert not np.allclose(plain_columns["ukf.beta_rad"], tilted_columns["ukf.beta_rad"])


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("estimate_disturbance", "KEY=VALUE"),
        ("=1", "KEY=VALUE"),
        ("bogus_key=1", "bogus_key"),
        ("disturbance_sigma_mps2=abc", "disturbance_sigma_mps2"),
        ("disturbance_sigma_mps2=[1", "not YAML"),
    ],
)
def test_a_bad_observer_setting_is_refused_naming_it(
    sim_bag_dir: Path, tmp_path: Path, capsys, setting: str, message: str
):
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "8"]
    args += ["--features", "measurable_observer_signals", "--prior", "ukf"]
    args += ["--observer-value", setting, "--out", str(tmp_path / "m.safetensors"), *TINY]
    assert train_main(args) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "m.safetensors").exists()


def test_an_observer_setting_is_refused_for_a_model_without_the_ukf(
    sim_bag_dir: Path, tmp_path: Path, capsys
):
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "8"]
    args += ["--features", "paper_kinematic", "--prior", "kinematic_window"]
    args += ["--observer-value", "estimate_disturbance=true"]
    assert train_main([*args, "--out", str(tmp_path / "m.safetensors"), *TINY]) == 2
    assert "does not read the UKF" in capsys.readouterr().err


def test_an_observer_setting_is_refused_beside_init(sim_bag_dir: Path, tmp_path: Path, capsys):
    start = tmp_path / "start.safetensors"
    train_ukf_residual(sim_bag_dir, start, "measurable_observer_signals")
    args = ["--data", str(sim_bag_dir), "--init", str(start), "--normalization", "keep"]
    args += ["--observer-value", "estimate_disturbance=true"]
    assert train_main([*args, "--out", str(tmp_path / "m.safetensors"), *TINY]) == 2
    assert "--observer-value does not go with --init" in capsys.readouterr().err
