"""Models that keep the physics: a residual on a kinematic prior and a model conditioned
on the car's nominal parameters train, export, and run in the estimator with the
trainer's output; the conditioning and the prior round-trip through the model file;
spun runs are used up to the spin; a separate validation fleet is honoured."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from sideslip_estimator.backends import BackendError, create_backend
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_msgs_py.artifact import read_artifact, write_artifact
from sideslip_msgs_py.fleet_envelope import FleetEnvelope
from sideslip_msgs_py.model_inputs import INPUT_SETS
from sideslip_msgs_py.vehicle_description import VehicleDescription
from sideslip_training import observer
from sideslip_training.cli import train_main
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import kinematic, outside_training_cars, predict_run
from sideslip_training.export import load_model

from .test_cli import TINY, _feed


def load_vehicle_dict(name: str) -> dict:
    """A shipped simulator car as its bags record it."""
    from sideslip_sim.vehicle import load_vehicle

    return {k: v for k, v in dataclasses.asdict(load_vehicle(name)).items() if k != "source_path"}


def car_files(record: dict, folder: Path) -> tuple[Path, Path]:
    """A recorded car's description and ``ukf`` params files, as a user writes them."""
    car, params = folder / "car.yaml", folder / "car.ukf.yaml"
    car.write_text(yaml.safe_dump(VehicleDescription.from_mapping(record).to_dict()))
    params.write_text(yaml.safe_dump(observer.params_of_vehicle(record)))
    return car, params


def train_ukf_residual(data: Path, out: Path, features: str, *extra: str) -> None:
    """A tiny residual on the UKF (8 units, 2 epochs) trained on ``data``."""
    args = ["--data", str(data), "--model", "lstm", "--hidden-units", "8"]
    args += ["--features", features, "--prior", "ukf", *extra]
    assert train_main([*args, "--out", str(out), *TINY]) == 0


@pytest.mark.parametrize(
    ("features", "prior"),
    [
        ("paper_kinematic", "kinematic_window"),
        ("measurable_invariant", "none"),
        ("measurable_observer", "ukf"),
    ],
)
def test_a_physics_model_runs_in_the_estimator_with_the_trainers_output(
    sim_bag_dir: Path, tmp_path: Path, features: str, prior: str
):
    model = tmp_path / f"{features}.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "8"]
    args += ["--features", features, "--prior", prior, "--out", str(model), *TINY]
    assert train_main(args) == 0
    _, meta = read_artifact(model)
    assert meta.features == INPUT_SETS[features] and meta.prior == prior
    config = json.loads((tmp_path / f"{features}.run" / "config.json").read_text())
    assert config["prior"] == prior

    runs, _ = load_runs([sim_bag_dir])
    run = runs[0]
    net, meta = load_model(model)
    # As the node's default: trained on simulated bags, averaged with its mirror image.
    expected = predict_run(net, meta, run, mirror_average="auto")
    values: dict[str, object] = {"model_file": str(model)}
    if meta.needs_vehicle:
        car = VehicleDescription.from_mapping(run.run_metadata["vehicle"])
        path = tmp_path / "car.yaml"
        path.write_text(yaml.safe_dump(car.to_dict()))
        values["vehicle_file"] = str(path)
    if meta.needs_observer:
        assert meta.observer == observer.default_values()
        path = tmp_path / "car.ukf.yaml"
        path.write_text(yaml.safe_dump(observer.params_of_vehicle(run.run_metadata["vehicle"])))
        values["observer_params_file"] = str(path)
        assert np.isfinite(expected).all()  # the filter runs from the first sample on
    backend = create_backend("pso_lstm", values, meta.window_steps)
    est = Estimator(backend, EstimatorParams(window_steps=meta.window_steps, max_gap_s=1.0))
    got = _feed(est, run.samples)
    assert len(got) == len(expected)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-6, equal_nan=True)


def test_an_observer_model_is_refused_without_the_cars_ukf_file(sim_bag_dir: Path, tmp_path: Path):
    model = tmp_path / "obs.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "8"]
    args += ["--features", "measurable_observer", "--prior", "ukf", "--out", str(model), *TINY]
    assert train_main(args) == 0
    car = tmp_path / "car.yaml"
    runs, _ = load_runs([sim_bag_dir])
    car.write_text(
        yaml.safe_dump(VehicleDescription.from_mapping(runs[0].run_metadata["vehicle"]).to_dict())
    )
    with pytest.raises(BackendError, match="observer_params_file"):
        create_backend("pso_lstm", {"model_file": str(model), "vehicle_file": str(car)}, 100)


def test_a_residual_model_starts_from_its_prior(sim_bag_dir: Path, tmp_path: Path):
    """An untrained-enough residual stays near the kinematic prior: β̂ − prior is the
    network's small output, never the whole β (the prior is added back)."""
    model = tmp_path / "residual.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "8"]
    args += ["--features", "paper_kinematic", "--prior", "kinematic_window"]
    assert train_main([*args, "--out", str(model), *TINY]) == 0
    net, meta = load_model(model)
    runs, _ = load_runs([sim_bag_dir])
    for run in runs:
        est = predict_run(net, meta, run)
        smoothed = kinematic(run, 20, meta.window_steps)
        # Both estimate β from Y_v: within a fraction of a degree of each other.
        assert np.max(np.abs(np.degrees(est - smoothed))) < 1.0


def test_a_model_that_reads_the_car_is_refused_without_one(sim_bag_dir: Path, tmp_path: Path):
    model = tmp_path / "cond.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "8"]
    args += ["--features", "measurable_invariant", "--out", str(model), *TINY]
    assert train_main(args) == 0
    with pytest.raises(BackendError, match="vehicle_file"):
        create_backend("pso_lstm", {"model_file": str(model)}, 100)


def test_conditioning_inputs_round_trip_through_the_model_file(tmp_path: Path, sim_bag_dir: Path):
    car = VehicleDescription(1320.0, 2.65, 1.1, 0.5, 1.5, 1.7, 0.31)
    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump(car.to_dict()))
    model = tmp_path / "fitted.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "8"]
    args += ["--features", "measurable_invariant", "--vehicle", str(path)]
    assert train_main([*args, "--out", str(model), *TINY]) == 0
    _, meta = read_artifact(model)
    assert VehicleDescription.from_mapping(meta.vehicle) == car
    assert [f for f in meta.features if f.startswith("vehicle.")] == [
        "vehicle.mass_kg",
        "vehicle.wheelbase_m",
        "vehicle.front_weight_fraction",
        "vehicle.cg_height_m",
    ]
    # The stored car is the default at deployment: no vehicle_file needed.
    backend = create_backend("pso_lstm", {"model_file": str(model)}, meta.window_steps)
    assert backend.meta.vehicle == car.to_dict()


def test_spun_runs_are_used_up_to_the_spin(tmp_path: Path):
    from sideslip_sim.generate import generate, single_vehicle
    from sideslip_sim.maneuvers import Maneuver
    from sideslip_sim.vehicle import load_vehicle

    # Rear drive on ice, full torque, a hard sine: it spins (tests/sideslip_sim/test_generate).
    severe = Maneuver("severe", "sine_steer", 6.0, 90.0, 900.0, stl_amplitude_m=0.12, mu=0.3)
    out = tmp_path / "bags"
    out.mkdir()
    (summary,) = generate(
        single_vehicle(load_vehicle("compact_rwd"), [severe]), out, progress=False
    )
    assert summary.spun
    runs, report = load_runs([out])
    kept = (runs[0].samples.stamp_ns[-1] - runs[0].samples.stamp_ns[0]) * 1e-9
    assert kept < summary.spin_onset_s
    assert np.max(np.abs(np.degrees(runs[0].samples.beta_rad()))) <= 30.0
    assert any("spun at" in line for line in report.lines)


def test_a_separate_validation_fleet_is_used_as_given(sim_bag_dir: Path, tmp_path: Path, capsys):
    val = tmp_path / "val"
    val.mkdir()
    for bag in ("sine_80", "straight_50"):
        (val / bag).symlink_to(sim_bag_dir / bag)
    train = tmp_path / "train"
    train.mkdir()
    for bag in ("dlc_70", "sine_60"):
        (train / bag).symlink_to(sim_bag_dir / bag)
    model = tmp_path / "m.safetensors"
    args = ["--data", str(train), "--val", str(val), "--model", "lstm", "--hidden-units", "8"]
    assert train_main([*args, "--out", str(model), *TINY]) == 0
    config = json.loads((tmp_path / "m.run" / "config.json").read_text())
    assert sorted(config["train_bags"]) == ["dlc_70", "dlc_70~mirror", "sine_60", "sine_60~mirror"]
    assert sorted(config["val_bags"]) == ["sine_80", "straight_50"]
    other = tmp_path / "other.safetensors"
    code = train_main([*args[:2], "--val", str(sim_bag_dir), *args[4:], "--out", str(other), *TINY])
    assert code == 2
    assert "--val shares 2 bag(s) with --data" in capsys.readouterr().err


def test_a_ukf_residual_publishes_the_ukf_on_a_car_outside_its_training_cars(
    sim_bag_dir: Path, tmp_path: Path
):
    model = tmp_path / "obs.safetensors"
    train_ukf_residual(sim_bag_dir, model, "measurable_observer_signals")
    _, meta = read_artifact(model)
    runs, _ = load_runs([sim_bag_dir])
    car, own_file = car_files(runs[0].run_metadata["vehicle"], tmp_path)
    own = yaml.safe_load(own_file.read_text())
    assert meta.envelope is not None and meta.envelope["cars"] == 1  # one simulated car
    assert FleetEnvelope.from_dict(meta.envelope).outside(own) == []
    base = {"model_file": str(model), "vehicle_file": str(car)}

    def estimates(values: dict[str, object]) -> tuple[list[float], tuple[str, ...]]:
        backend = create_backend("pso_lstm", {**base, **values}, 100)
        est = Estimator(backend, EstimatorParams(window_steps=100, max_gap_s=1.0))
        return _feed(est, runs[0].samples), backend.caveats

    _, caveats = estimates({"observer_params_file": str(own_file)})
    assert caveats == ()
    # compact_rwd is not the training car: its quantities lie outside a one-car envelope.
    fallback, caveats = estimates({"observer_params_file": "compact_rwd"})
    assert len(caveats) == 1 and "publishing the UKF's estimate" in caveats[0]
    assert "outside obs.safetensors's 1 training cars" in caveats[0]
    ukf = create_backend("ukf", {"params_file": "compact_rwd"}, 100)
    reference = _feed(
        Estimator(ukf, EstimatorParams(window_steps=100, max_gap_s=1.0)), runs[0].samples
    )
    assert fallback == reference
    network, caveats = estimates(
        {"observer_params_file": "compact_rwd", "outside_fleet": "network"}
    )
    assert "publishing the model's estimate" in caveats[0]
    assert len(network) == len(reference) and network != reference
    with pytest.raises(BackendError, match=r"outside_fleet refuse: car compact_rwd outside"):
        create_backend(
            "pso_lstm",
            {**base, "observer_params_file": "compact_rwd", "outside_fleet": "refuse"},
            100,
        )
    with pytest.raises(BackendError, match=r"outside_fleet must be one of"):
        create_backend(
            "pso_lstm",
            {**base, "observer_params_file": "compact_rwd", "outside_fleet": "x"},
            100,
        )


def test_offline_scoring_answers_as_the_node_on_a_car_outside_the_training_cars(
    sim_bag_dir: Path, tmp_path: Path
):
    trained = tmp_path / "obs.safetensors"
    train_ukf_residual(sim_bag_dir, trained, "measurable_observer")
    tensors, meta = read_artifact(trained)
    # The same network, told it was trained on compact_rwd only: the bags' car is outside.
    other = FleetEnvelope.of_cars([observer.params_of_vehicle(load_vehicle_dict("compact_rwd"))])
    model = tmp_path / "elsewhere.safetensors"
    write_artifact(model, tensors, dataclasses.replace(meta, envelope=other.to_dict()))
    runs, _ = load_runs([sim_bag_dir])
    run = runs[0]
    assert outside_training_cars(read_artifact(model)[1], run)
    net, meta = load_model(model)
    offline = predict_run(net, meta, run)
    car, own = car_files(run.run_metadata["vehicle"], tmp_path)
    values = {"model_file": str(model), "observer_params_file": str(own), "vehicle_file": str(car)}
    backend = create_backend("pso_lstm", values, meta.window_steps)
    assert "publishing the UKF's estimate" in backend.caveats[0]
    est = Estimator(backend, EstimatorParams(window_steps=meta.window_steps, max_gap_s=1.0))
    np.testing.assert_allclose(_feed(est, run.samples), offline, rtol=0, atol=1e-12)
    network = predict_run(net, meta, run, outside_fleet="network")
    assert np.nanmax(np.abs(network - offline)) > 0


def test_a_ukf_model_of_a_recording_without_a_car_is_tested_with_the_given_car(
    sim_bag_dir: Path, tmp_path: Path, make_arrays, write_arrays
):
    recording = tmp_path / "recording"
    for k in range(2):  # as a real logger writes them: no vehicle record in the bags
        write_arrays(f"drive{k}", make_arrays(1500, seed=k), recording)
    runs, _ = load_runs([sim_bag_dir])
    car, params = car_files(runs[0].run_metadata["vehicle"], tmp_path)
    model = tmp_path / "rec.safetensors"
    options = ["--split", "time", "--test-fraction", "0.3"]
    options += ["--observer-params", str(params), "--vehicle", str(car)]
    train_ukf_residual(recording, model, "measurable_observer_signals", *options)
    metrics = json.loads((tmp_path / "rec.run" / "metrics.json").read_text())
    ours = next(v for k, v in metrics["test"].items() if k.startswith("LSTM"))
    assert ours["samples"] > 0 and np.isfinite(ours["mae_deg"])
    _, meta = read_artifact(model)
    assert meta.envelope is not None and meta.envelope["cars"] == 1  # the given car


def test_mixed_cars_give_each_bag_its_true_or_described_car_by_its_name(sim_bag_dir: Path):
    """--car mixed: a bag's UKF runs on its described car or its true one, fixed by the
    bag's name (its segments and mirror image share the side), about half each."""
    run = load_runs([sim_bag_dir])[0][0]
    true_params = observer.run_params(run, None)[0]
    described = observer.run_params(run, None, car="described")[0]
    sides = {}
    for name in (f"fleet1_car{i:03d}_0_cornering" for i in range(200)):
        named = dataclasses.replace(run, name=name, bag=name)
        got = observer.run_params(named, None, car="mixed")[0]
        assert got in (true_params, described)
        sides[name] = got == described
        segment = dataclasses.replace(named, name=name + "#1")
        assert (observer.run_params(segment, None, car="mixed")[0] == described) == sides[name]
    assert 70 <= sum(sides.values()) <= 130  # a fair coin over 200 names: ±4.2 SD
    assert all(sides[n] == observer.described_half(n) for n in sides)


def test_a_given_car_replaces_the_bags_own_car_in_training_and_scoring(
    sim_bag_dir: Path, tmp_path: Path
):
    """--car given: the UKF and the car's inputs read the files a user gives the node,
    also for bags that record their (true) car: sideslip-fit trains on described cars."""
    runs, _ = load_runs([sim_bag_dir])
    run = runs[0]
    true_car = run.run_metadata["vehicle"]
    other = load_vehicle_dict("compact_rwd")
    car, params = car_files(other, tmp_path)
    assert observer.run_params(run, str(params))[0] == observer.params_of_vehicle(true_car)
    given = observer.run_params(run, str(params), car="given")[0]
    assert given == observer.params_of_vehicle(other)
    with pytest.raises(observer.DatasetError, match="the given car"):
        observer.run_params(run, None, car="given")
    # described: the bag's car as its description alone tells it (no file needed).
    from sideslip_sim.described_car import described_vehicle

    nominal = VehicleDescription.from_mapping(true_car).to_dict()
    guess = described_vehicle(name="x", layout=true_car["drive_layout"], **nominal)
    described = observer.run_params(run, None, car="described")[0]
    expected = observer.params_of_vehicle(
        {k: v for k, v in dataclasses.asdict(guess).items() if k != "source_path"}
    )
    assert {k: v for k, v in described.items() if k != "name"} == {
        **{k: v for k, v in expected.items() if k != "name"},
        "axles_from": "description",  # the σ for described files goes with it
    }
    assert described["mf_b_rear"] != observer.params_of_vehicle(true_car)["mf_b_rear"]

    plain, as_given = tmp_path / "plain.safetensors", tmp_path / "given.safetensors"
    files = ["--vehicle", str(car), "--observer-params", str(params)]
    train_ukf_residual(sim_bag_dir, plain, "measurable_observer", *files)
    train_ukf_residual(sim_bag_dir, as_given, "measurable_observer", *files, "--car", "given")
    # The training cars are the bags' car, or only the given one.
    envelope = FleetEnvelope.from_dict(read_artifact(as_given)[1].envelope)
    assert not envelope.outside(observer.params_of_vehicle(other), "given")
    assert FleetEnvelope.from_dict(read_artifact(plain)[1].envelope).outside(
        observer.params_of_vehicle(other), "given"
    )
    # Scored as the node runs it with those files: another answer than with the true car.
    net, meta = load_model(as_given)
    options = {"vehicle": VehicleDescription.load(car), "observer_params_file": str(params)}
    own = predict_run(net, meta, run, **options)
    with_given = predict_run(net, meta, run, **options, car="given")
    assert np.nanmax(np.abs(with_given - own)) > 1e-4
    # Without the files it asks for, --car given is refused before any training.
    assert train_main(["--data", str(sim_bag_dir), "--model", "lstm", "--features",
                       "measurable_observer", "--prior", "ukf", "--car", "given",
                       "--out", str(tmp_path / "x.safetensors"), *TINY]) == 2  # fmt: skip
