"""Noise tuning of the ukf back-end with PSO on (tiny) training bags."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from sideslip_estimator.backends import create_backend
from sideslip_estimator.backends.ukf import TUNED_PARAMETERS, UkfBackend
from sideslip_msgs_py.sample import SampleArrays
from sideslip_training.config import PsoSettings
from sideslip_training.ukf_tuning import (
    TuningError,
    beta_rmse_deg,
    load_replay_runs,
    main,
    search_space,
    tune,
)

DEFAULTS = {p.name: p.default for p in UkfBackend.parameters}


@pytest.fixture(scope="module")
def two_bags(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two generated 2-s runs with paper noise (sine steer, lane change)."""
    from sideslip_sim.generate import generate, single_vehicle
    from sideslip_sim.maneuvers import Maneuver
    from sideslip_sim.vehicle import load_vehicle

    out = tmp_path_factory.mktemp("ukf_bags")
    maneuvers = [
        Maneuver("sine_70", "sine_steer", 2.0, 70.0, 300.0, ay_fraction=0.6),
        Maneuver("dlc_60", "double_lane_change", 2.0, 60.0, 300.0),
    ]
    generate(single_vehicle(load_vehicle("paper_sedan"), maneuvers), out, progress=False)
    return out


def test_two_particles_one_iteration_tune_within_the_search_box(two_bags: Path) -> None:
    runs = load_replay_runs([two_bags])
    assert sorted(r.name for r in runs) == ["dlc_60", "sine_70"]
    result = tune(runs, "paper_sedan", PsoSettings(iterations=1, swarm_size=2, seed=3))
    assert result.pso_evaluations == 4
    assert result.samples == 1600
    assert math.isfinite(result.default_rmse_deg) and result.default_rmse_deg < 0.5
    # The defaults are a candidate too: tuning never makes the training fit worse.
    assert result.best_rmse_deg <= result.default_rmse_deg
    assert set(result.best_values) == set(TUNED_PARAMETERS)
    for name, value in result.best_values.items():
        assert DEFAULTS[name] / 10.0 * 0.999 <= value <= DEFAULTS[name] * 10.0 * 1.001, name
    # The chosen values build the back-end and reproduce the reported fit.
    create_backend("ukf", result.best_values, 100)
    assert beta_rmse_deg(runs, result.best_values) == pytest.approx(result.best_rmse_deg, rel=1e-3)
    json.loads(result.to_json())  # strict JSON, history included


def test_search_space_is_log10_around_the_defaults_and_refuses_unknown_names() -> None:
    space = search_space(["lateral_acceleration_sigma_mps2"], decades=0.5)
    (dim,) = space
    c = math.log10(float(DEFAULTS["lateral_acceleration_sigma_mps2"]))
    assert dim.name == "log10_lateral_acceleration_sigma_mps2"
    assert (dim.low, dim.high) == pytest.approx((c - 0.5, c + 0.5))
    with pytest.raises(TuningError, match="min_speed_mps"):
        search_space(["min_speed_mps"])


def test_bad_fixed_settings_are_refused_before_any_replay(two_bags: Path) -> None:
    runs = load_replay_runs([two_bags / "sine_70"])
    with pytest.raises(TuningError, match="params_file"):
        tune(runs, "hovercraft", PsoSettings(iterations=0, swarm_size=1))


def test_cli_writes_json_and_never_overwrites_without_force(
    two_bags: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "tuning.json"
    args = ["--data", str(two_bags / "sine_70"), "--swarm", "2", "--iterations", "0",
            "--names", "process_sigma_lateral_mps2", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    data = json.loads(out.read_text())
    assert list(data["best_values"]) == ["process_sigma_lateral_mps2"]
    assert "ukf.process_sigma_lateral_mps2" in capsys.readouterr().out
    assert main(args) == 2
    assert "exists" in capsys.readouterr().err
    assert main([*args, "--force"]) == 0


def test_cli_without_bags_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["--data", str(tmp_path)]) == 2
    assert "no bags" in capsys.readouterr().err


@pytest.fixture(scope="module")
def compact_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One 2-s sine-steer run of another car than the shipped default's."""
    from sideslip_sim.generate import generate, single_vehicle
    from sideslip_sim.maneuvers import Maneuver
    from sideslip_sim.vehicle import load_vehicle

    out = tmp_path_factory.mktemp("ukf_compact")
    maneuvers = [Maneuver("sine_70", "sine_steer", 2.0, 70.0, 300.0, ay_fraction=0.6)]
    generate(single_vehicle(load_vehicle("compact_rwd"), maneuvers), out, progress=False)
    return out


def test_recorded_cars_replay_each_bag_with_its_own_car(compact_bag: Path, tmp_path: Path) -> None:
    from sideslip_msgs_py.bag import read_bag
    from sideslip_training.observer import BACKEND, params_of_vehicle
    from sideslip_training.physics_params import params_yaml
    from sideslip_training.ukf_tuning import replay

    (run,) = load_replay_runs([compact_bag], recorded=True)
    assert run.car_params is not None and run.stl_limit_m is not None
    vehicle = read_bag(compact_bag / "sine_70").run_metadata["vehicle"]
    own = tmp_path / "compact.ukf.yaml"
    own.write_text(params_yaml(BACKEND, "compact_rwd", params_of_vehicle(vehicle), "test"))
    (plain,) = load_replay_runs([compact_bag])
    assert plain.car_params is None
    recorded = replay(run, DEFAULTS)
    # The same as giving that car's file by hand, and not the default car's estimate.
    by_hand = replay(plain, {**DEFAULTS, "params_file": str(own)})
    assert recorded == pytest.approx(by_hand, nan_ok=True)
    default_car = replay(plain, DEFAULTS)
    ok = ~(np.isnan(recorded) | np.isnan(default_car))
    assert ok.sum() > 500 and np.max(np.abs(recorded[ok] - default_car[ok])) > 1e-4
    result = tune([run], "recorded", PsoSettings(iterations=0, swarm_size=1))
    assert result.default_rmse_deg == pytest.approx(beta_rmse_deg([run], DEFAULTS))


def test_recorded_cars_refuse_a_bag_without_a_car_by_name(
    make_arrays: Callable[..., SampleArrays],
    write_arrays: Callable[..., Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    write_arrays("no_car", make_arrays(400), folder=tmp_path / "anonymous")
    with pytest.raises(TuningError, match=r"no_car.*records no vehicle"):
        load_replay_runs([tmp_path / "anonymous"], recorded=True)
    assert main(["--data", str(tmp_path / "anonymous"), "--params-file", "recorded"]) == 2
    assert "records no vehicle" in capsys.readouterr().err
