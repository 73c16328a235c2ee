"""A network averaged with its mirror image (``pso_lstm.mirror_average``,
``sideslip-evaluate --mirror-average``): the model inputs of a mirrored run are the
declared signs times the run's own, the UKF's included; the averaged estimate of the
mirrored run is exactly minus that of the run; the node and the trainer agree."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sideslip_estimator.backends import create_backend
from sideslip_estimator.backends.base import BackendError
from sideslip_estimator.backends.model_files import shipped_models
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_msgs_py.artifact import read_artifact, write_artifact
from sideslip_msgs_py.data_source import learnt_from_simulation_only
from sideslip_msgs_py.mirror import input_signs, mirrored
from sideslip_msgs_py.model_inputs import INPUT_SETS
from sideslip_msgs_py.vehicle_description import VehicleDescription
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import predict_run
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve
from sideslip_training.inputs import InputSpec

from .test_cli import _feed
from .test_physics_models import car_files


def _flip(run):  # type: ignore[no-untyped-def]
    return dataclasses.replace(run, name=run.name + "~m", samples=mirrored(run.samples))


def test_the_inputs_of_a_mirrored_run_are_the_declared_signs_times_the_runs_own(
    sim_bag_dir: Path,
) -> None:
    """Checked through the real filter: the UKF's β̂ and innovations change sign with
    the drive, its μ̂ does not."""
    run = load_runs([sim_bag_dir])[0][0]
    car = VehicleDescription.from_mapping(run.run_metadata["vehicle"])
    names = (*INPUT_SETS["measurable_observer"], "ukf.road_friction")
    names = tuple(dict.fromkeys(names))
    _, meta = load_model(resolve("fleet_ukf_measurable"))
    spec = InputSpec(names, "ukf", 0.0025, car, meta.observer, None)
    plain, flipped = spec.inputs(run), spec.inputs(_flip(run))
    ok = np.isfinite(plain).all(axis=1)
    assert ok.mean() > 0.9
    np.testing.assert_allclose(flipped[ok], plain[ok] * input_signs(names), rtol=0, atol=1e-9)


@pytest.mark.parametrize("engine", ["numba", "torch"])
def test_the_mirror_averaged_estimate_is_odd_and_the_node_gives_the_trainers(
    sim_bag_dir: Path, tmp_path: Path, engine: str
) -> None:
    run = load_runs([sim_bag_dir])[0][0]
    vehicle, params = car_files(run.run_metadata["vehicle"], tmp_path)
    net, meta = load_model(resolve("fleet_ukf_measurable"))
    # paper_sedan lies outside the model's training cars: run the network anyway.
    kwargs = {"outside_fleet": "network", "mirror_average": True}
    expected = predict_run(net, meta, run, **kwargs)
    of_flipped = predict_run(net, meta, _flip(run), **kwargs)
    plain = predict_run(net, meta, run, outside_fleet="network")
    ok = np.isfinite(expected)
    assert ok.mean() > 0.9
    np.testing.assert_allclose(of_flipped[ok], -expected[ok], rtol=0, atol=1e-7)
    assert np.abs(plain[ok] - expected[ok]).max() > 1e-5  # the network is not odd itself
    values = {
        "model_file": "fleet_ukf_measurable",
        "vehicle_file": str(vehicle),
        "observer_params_file": str(params),
        "outside_fleet": "network",
        "mirror_average": True,
        "engine": engine,
    }
    backend = create_backend("pso_lstm", values, meta.window_steps)
    assert "averaged with its mirror image" in backend.model_id
    est = Estimator(backend, EstimatorParams(window_steps=meta.window_steps, max_gap_s=1.0))
    got = np.array(_feed(est, run.samples))
    assert got.size == expected[ok].size
    np.testing.assert_allclose(got, expected[ok], rtol=0, atol=1e-6)


@pytest.mark.parametrize(("recordings", "averaged"), [(0, True), (3, False), (None, False)])
def test_auto_averages_only_a_model_that_records_it_learnt_from_simulation_alone(
    tmp_path: Path, recordings: int | None, averaged: bool
) -> None:
    """The node's default (``auto``): on for simulation alone; off for a model fitted to
    recordings (their offsets kept) and for a file that does not say; true and false
    (also as bools, as ``-p pso_lstm.mirror_average:=true`` gives them) as set."""
    tensors, meta = read_artifact(resolve("fleet_lstm_paper"))
    provenance = {k: v for k, v in meta.provenance.items() if k != "recordings"}
    if recordings is not None:
        provenance["recordings"] = recordings
    path = write_artifact(
        tmp_path / "m.safetensors", tensors, dataclasses.replace(meta, provenance=provenance)
    )
    w = meta.window_steps

    def backend(**values: object):  # type: ignore[no-untyped-def]
        return create_backend("pso_lstm", {"model_file": str(path), **values}, w)

    assert backend().mirror_average is averaged
    assert ("averaged with its mirror image" in backend().model_id) is averaged
    assert backend(mirror_average="true").mirror_average
    assert backend(mirror_average=True).mirror_average
    assert not backend(mirror_average=False).mirror_average
    assert not backend(mirror_average="false").mirror_average
    with pytest.raises(BackendError, match=r"pso_lstm\.mirror_average must be one of auto, true"):
        backend(mirror_average="sometimes")


def test_every_shipped_fleet_model_records_it_learnt_from_simulation_alone() -> None:
    """So the node averages each with its mirror image by default; the paper's
    reproduction models, written before the record existed, stay as they were."""
    for name in shipped_models():
        _, meta = read_artifact(resolve(name))
        expected = True if name.startswith("fleet_") else None
        assert learnt_from_simulation_only(meta.provenance) is expected, name
