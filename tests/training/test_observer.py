"""The UKF observer's columns for models anchored on it: what the estimator's ukf back-end
gives sample by sample, cached by content, from the bag's car or a given params file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from sideslip_msgs_py.model_inputs import OBSERVER_COLUMNS
from sideslip_training import observer
from sideslip_training.dataset import DatasetError, load_runs
from sideslip_training.inputs import InputSpec


def test_columns_are_the_ukf_back_ends_estimates_and_are_cached(sim_bag_dir: Path):
    from sideslip_estimator.backends import create_backend

    runs, _ = load_runs([sim_bag_dir])
    run = runs[0]
    values = observer.default_values()
    first = observer.columns(run, values)
    assert set(first) == set(OBSERVER_COLUMNS)
    assert all(len(v) == len(run.samples) for v in first.values())
    assert np.isfinite(first["ukf.beta_rad"]).all()
    # What the back-end itself gives on the same rows, one sample at a time.
    params = observer.params_of_vehicle(run.run_metadata["vehicle"])
    path = Path(observer.cache_dir()).parent / "car.ukf.yaml"
    path.write_text(yaml.safe_dump(params))
    ukf = create_backend("ukf", {**values, "params_file": str(path)}, 100)
    s = run.samples
    rows = np.column_stack(
        [s.x_v_mps, s.y_v_mps, s.x_a_mps2, s.y_a_mps2, s.yaw_rate_radps, s.stl_m]
    )
    for i in range(50):
        got = ukf.update(rows[: i + 1], s.stamp_ns[: i + 1])
        assert got is not None and got.beta_rad == first["ukf.beta_rad"][i]

    cached = sorted(observer.cache_dir().glob("*.npz"))
    again = observer.columns(run, values)
    assert sorted(observer.cache_dir().glob("*.npz")) == cached  # read, not recomputed
    for c in OBSERVER_COLUMNS:
        np.testing.assert_array_equal(again[c], first[c])
    # Other filter settings are another entry.
    other = observer.columns(run, {**values, "estimate_friction": False})
    assert len(list(observer.cache_dir().glob("*.npz"))) == len(cached) + 1
    assert np.all(other["ukf.road_friction"] == values["friction_initial"])


def test_a_mirror_image_is_filtered_once_its_odd_columns_negated(
    sim_bag_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """--mirror / --mirror-val: a run's mirror image is not filtered again; its columns
    are the run's with the odd ones negated, as the (symmetric) filter itself gives."""
    from sideslip_training.training_data import with_mirrored

    monkeypatch.setenv("SIDESLIP_CACHE", str(tmp_path / "cache"))  # a cache of its own
    run, twin = with_mirrored([load_runs([sim_bag_dir])[0][0]])
    values = observer.default_values()
    observer.precompute([run, twin], values, progress=False)
    assert len(list(observer.cache_dir().glob("*.npz"))) == 1
    derived, own = observer.columns(twin, values), observer.columns(run, values)
    params, stl = observer.run_params(twin, None)
    filtered = observer.compute(twin, params, values, stl)
    for c in OBSERVER_COLUMNS:
        np.testing.assert_allclose(derived[c], filtered[c], rtol=0, atol=1e-9, err_msg=c)
    np.testing.assert_array_equal(derived["ukf.beta_rad"], -own["ukf.beta_rad"])
    np.testing.assert_array_equal(derived["ukf.road_friction"], own["ukf.road_friction"])
    assert len(list(observer.cache_dir().glob("*.npz"))) == 1


def test_a_run_cut_in_time_reads_the_filter_that_ran_through_the_cut(
    sim_bag_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """A split in time and a fold's blocks: the pieces' columns are the whole run's at
    their samples (the node ran through the cut), not a filter started again at it;
    their mirror images too, and the recording is filtered once for all its pieces."""
    from sideslip_training.cross_validation import fold_runs
    from sideslip_training.splits import split_in_time
    from sideslip_training.training_data import with_mirrored

    monkeypatch.setenv("SIDESLIP_CACHE", str(tmp_path / "cache"))
    run = load_runs([sim_bag_dir])[0][0]
    values = observer.default_values()
    whole = observer.columns(run, values)
    head, tail = split_in_time([run], 0.4, "val")
    blocks = [r for g in fold_runs([*head, *tail], 3, "time", 0) for r in g]
    pieces = with_mirrored([*head, *tail, *blocks])
    observer.precompute(pieces, values, progress=False)
    assert len(list(observer.cache_dir().glob("*.npz"))) == 1  # the whole run's
    for piece in pieces:
        got = observer.columns(piece, values)
        n, k = len(piece.samples), piece.offset
        sign = -1.0 if piece.name.endswith("~mirror") else 1.0
        np.testing.assert_array_equal(got["ukf.beta_rad"], sign * whole["ukf.beta_rad"][k : k + n])
        np.testing.assert_array_equal(
            got["ukf.road_friction"], whole["ukf.road_friction"][k : k + n]
        )
    # What a filter started again at the cut would have given: not the same.
    params, stl = observer.run_params(tail[0], None)
    fresh = observer.compute(tail[0], params, values, stl)["ukf.beta_rad"]
    assert tail[0].offset > 0
    assert not np.allclose(fresh[:50], whole["ukf.beta_rad"][tail[0].offset :][:50])


def test_a_recording_without_a_car_needs_the_ukf_params_file(make_arrays, write_arrays):
    bag = write_arrays("real_car", make_arrays(300))
    runs, _ = load_runs([bag])
    spec = InputSpec(("x_v_mps", "ukf.beta_rad"), "ukf")
    with pytest.raises(DatasetError, match="give the car's ukf params file"):
        spec.inputs(runs[0])


def test_observer_values_are_the_ukf_back_ends_parameters():
    assert "params_file" not in observer.default_values()
    with pytest.raises(DatasetError, match="params_file is per car"):
        observer.check_values({"params_file": "paper_sedan"})
    with pytest.raises(DatasetError, match="unknown parameter"):
        observer.check_values({"min_speed": 3.0})
    with pytest.raises(DatasetError, match="observer values given"):
        InputSpec(("x_v_mps",), "none", observer={"min_speed_mps": 3.0})


def test_a_run_with_its_own_car_source_keeps_its_record_when_the_given_car_is_asked(
    sim_bag_dir: Path, tmp_path: Path
):
    """``--rehearse`` runs (``car_source="recorded"``) read their simulated car's true
    parameters beside recordings run with the given files (``--car given``)."""
    import dataclasses

    from sideslip_msgs_py.vehicle_description import VehicleDescription

    run = load_runs([sim_bag_dir])[0][0]
    record = run.run_metadata["vehicle"]
    other = {**observer.params_of_vehicle(record), "mass_kg": 2222.0}
    given = tmp_path / "given.ukf.yaml"
    given.write_text(yaml.safe_dump(other))
    assert observer.run_params(run, str(given), car="given")[0]["mass_kg"] == 2222.0
    own = dataclasses.replace(run, car_source="recorded")
    assert observer.run_params(own, str(given), car="given")[0] == observer.params_of_vehicle(
        record
    )
    vehicle = VehicleDescription.from_mapping({**record, "mass_kg": 2222.0})
    spec = InputSpec(("x_v_mps", "vehicle.mass_kg"), "none", vehicle=vehicle, car="given")
    assert spec.run_vehicle(run) == vehicle
    assert spec.run_vehicle(own) == VehicleDescription.from_mapping(record)


def test_where_a_runs_axle_curves_come_from_follows_the_car_source(sim_bag_dir: Path, tmp_path):
    """The σ a model publishes follows this: recorded cars are ``vehicle``, described
    ones ``description``, a given file says itself; a value it cannot mean is refused
    (a cached filter run must not hide a typo)."""
    from importlib import resources

    run = load_runs([sim_bag_dir])[0][0]
    assert observer.axles_from(run, None) == "vehicle"
    assert observer.axles_from(run, None, car="described") == "description"
    shipped = resources.files("sideslip_estimator").joinpath("data/ukf/compact_rwd.yaml")
    data = yaml.safe_load(shipped.read_text())
    for value in ("recordings", "Description"):
        path = tmp_path / f"{value}.yaml"
        path.write_text(yaml.safe_dump({**data, "axles_from": value}))
        if value == "recordings":
            assert observer.axles_from(run, str(path), car="given") == "recordings"
        else:
            with pytest.raises(DatasetError, match=r"axles_from must be one of .*'Description'"):
                observer.axles_from(run, str(path), car="given")
