"""The fleet sampler, its plausibility checks, per-axle tyres and roll steer, and the
held-out cars that no training preset may contain."""

from __future__ import annotations

import dataclasses
import json
from collections import Counter

import numpy as np
import pytest
import yaml

from sideslip_msgs_py.bag import read_bag
from sideslip_sim import dynamics as dyn
from sideslip_sim.fleet import TIRE_CHARACTERISTICS, FleetRanges, sample_fleet, vehicle_digest
from sideslip_sim.generate_cli import main
from sideslip_sim.held_out import HELD_OUT_NAMES, held_out_digests, held_out_vehicles
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.plausibility import plausibility, plausibility_problems
from sideslip_sim.presets import fleet, held_out, paper_train, randomized
from sideslip_sim.simulate import prepare, simulate
from sideslip_sim.single_track import SingleTrack
from sideslip_sim.tire import DEFAULT_TIR, load_tire
from sideslip_sim.vehicle import load_vehicle, vehicle_from_dict

TIRE = load_tire(str(DEFAULT_TIR))


@pytest.fixture(scope="module")
def drawn():
    return sample_fleet(120, seed=11)


def test_same_seed_draws_the_same_cars_and_another_seed_other_cars():
    first = [vehicle_digest(v) for v in sample_fleet(8, seed=3).vehicles]
    again = [vehicle_digest(v) for v in sample_fleet(8, seed=3).vehicles]
    other = [vehicle_digest(v) for v in sample_fleet(8, seed=4).vehicles]
    assert first == again
    assert not set(first) & set(other)


def test_every_sampled_car_is_plausible_and_within_the_stated_ranges(drawn):
    ranges = FleetRanges()
    for car in drawn.vehicles:
        assert plausibility_problems(car, TIRE) == [], car.name
        assert ranges.mass_kg[0] <= car.mass_kg <= ranges.mass_kg[1]
        assert ranges.wheelbase_m[0] <= car.wheelbase_m <= ranges.wheelbase_m[1]
        front = car.cg_to_rear_axle_m / car.wheelbase_m
        assert ranges.front_weight_fraction[0] - 1e-6 <= front <= ranges.front_weight_fraction[1]
        assert ranges.cg_height_m[0] <= car.cg_height_m <= ranges.cg_height_m[1]
        index = car.yaw_inertia_kgm2 / (
            car.mass_kg * car.cg_to_front_axle_m * car.cg_to_rear_axle_m
        )
        assert ranges.dynamic_index[0] - 1e-4 <= index <= ranges.dynamic_index[1] + 1e-4
        for track in (car.track_front_m, car.track_rear_m):
            assert ranges.track_m[0] <= track <= ranges.track_m[1]


def test_the_fleet_spans_layouts_tyres_masses_and_steering_ratios(drawn):
    cars = drawn.vehicles
    assert set(Counter(c.drive_layout for c in cars)) == {"fwd", "rwd", "awd"}
    characters = {c.description.split(", ")[-1].removesuffix(" tyres") for c in cars}
    assert characters == set(TIRE_CHARACTERISTICS)
    masses = np.array([c.mass_kg for c in cars])
    assert masses.min() < 1100 and masses.max() > 2300
    ratios = np.array([c.stl_per_road_wheel_angle_m_per_rad for c in cars])
    assert ratios.max() / ratios.min() > 1.4
    assert any(c.roll_steer_front_rad_per_rad > 0.05 for c in cars)
    friction = {round(c.tire_peak_friction_scale_front, 2) for c in cars}
    assert len(friction) > 10


def test_plausibility_checks_reject_an_oversteering_or_top_heavy_car():
    car = held_out_vehicles()["heldout_sedan_rwd"]
    assert plausibility_problems(car, TIRE) == []
    oversteer = dataclasses.replace(car, tire_cornering_stiffness_scale_rear=0.6)
    assert plausibility(oversteer, TIRE).understeer_gradient_deg_per_g < 0.5
    assert any("understeer" in p for p in plausibility_problems(oversteer, TIRE))
    tall = dataclasses.replace(car, cg_height_m=0.95)
    assert any("stability" in p for p in plausibility_problems(tall, TIRE))


def test_held_out_cars_are_plausible_and_the_six_the_benchmark_names():
    cars = held_out_vehicles()
    assert tuple(cars) == HELD_OUT_NAMES
    expected_mass = {
        "heldout_hatchback_fwd": 1050, "heldout_sedan_rwd": 1550, "heldout_suv_awd": 2150,
        "heldout_sports_rwd": 1400, "heldout_van_fwd": 2500, "heldout_ev_awd": 2100,
    }  # fmt: skip
    for name, car in cars.items():
        assert car.mass_kg == pytest.approx(expected_mass[name], abs=1.0)
        assert plausibility_problems(car, TIRE) == [], name
        assert car.drive_layout == name.rsplit("_", 1)[1]
    assert cars["heldout_suv_awd"].cg_height_m > 0.7
    assert cars["heldout_ev_awd"].cg_to_front_axle_m == pytest.approx(
        cars["heldout_ev_awd"].cg_to_rear_axle_m
    )
    sports = cars["heldout_sports_rwd"]
    assert sports.tire_cornering_stiffness_scale_front > 1.2  # stiff performance tyres


def test_held_out_cars_are_absent_from_every_training_preset():
    digests = held_out_digests()
    assert len(digests) == 6
    for seed in range(4):
        assert not {vehicle_digest(r.vehicle) for r in fleet(40, seed)} & digests
    for name in ("paper_sedan", "compact_rwd"):  # the one-car presets' shipped cars
        assert vehicle_digest(load_vehicle(name)) not in digests
    assert paper_train() and randomized(5, 0)  # one-car presets: the car is --vehicle


def test_the_sampler_never_draws_an_excluded_digest():
    first = sample_fleet(1, seed=21).vehicles[0]
    redrawn = sample_fleet(1, seed=21, exclude_digests=frozenset({vehicle_digest(first)}))
    assert vehicle_digest(redrawn.vehicles[0]) != vehicle_digest(first)
    assert redrawn.rejected["identical to"] == 1


def test_a_held_out_car_written_to_yaml_reads_back_with_the_same_digest(tmp_path):
    car = held_out_vehicles()["heldout_van_fwd"]
    data = {k: v for k, v in dataclasses.asdict(car).items() if k != "source_path"}
    path = tmp_path / "van.yaml"
    path.write_text(yaml.safe_dump(data))
    assert vehicle_digest(load_vehicle(path)) == vehicle_digest(car)


def test_generate_refuses_a_held_out_car_in_a_training_preset(tmp_path, capsys):
    car = held_out_vehicles()["heldout_sports_rwd"]
    path = tmp_path / "sports.yaml"
    data = {k: v for k, v in dataclasses.asdict(car).items() if k != "source_path"}
    path.write_text(yaml.safe_dump(data))
    rc = main(["--preset", "paper-train", "--vehicle", str(path), "--out", str(tmp_path / "o")])
    assert rc == 2
    assert "held-out car" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
    rc = main(["--preset", "fleet", "--vehicle", "paper_sedan", "--out", str(tmp_path / "f")])
    assert rc == 2


def test_fleet_bags_record_each_cars_full_parameters_digest_and_checks(tmp_path):
    out = tmp_path / "fleet"
    assert main(["--preset", "fleet", "--count", "2", "--out", str(out), "--quiet"]) == 0
    runs = fleet(2, 0)
    index = json.loads((out / "index.json").read_text())
    assert [r["vehicle"] for r in index["runs"]] == [r.vehicle.name for r in runs]
    meta = read_bag(out / runs[0].maneuver.name).run_metadata
    car = vehicle_from_dict(meta["vehicle"])
    assert vehicle_digest(car) == meta["vehicle_digest"] == vehicle_digest(runs[0].vehicle)
    assert meta["vehicle_checks"]["static_stability_factor"] > 1.0
    assert "spin_onset_s" in meta


def test_held_out_benchmark_drives_every_car_at_three_frictions_through_six_runs():
    runs = held_out()
    assert len(runs) == 6 * 3 * 6
    cells = Counter((r.vehicle.name, r.maneuver.mu) for r in runs)
    assert set(cells.values()) == {6}
    kinds = {r.maneuver.scenario or r.maneuver.family for r in runs}
    assert kinds == {"scen1", "scen2", "scen3", "scen4", "step_steer", "sweep_steer"}


def test_axle_tyre_scaling_scales_each_axles_cornering_stiffness():
    car = load_vehicle("compact_rwd")
    base = SingleTrack.from_vehicle(car, TIRE)
    scaled = SingleTrack.from_vehicle(
        dataclasses.replace(
            car, tire_cornering_stiffness_scale_front=1.2, tire_cornering_stiffness_scale_rear=0.8
        ),
        TIRE,
    )
    assert scaled.c_front_n_per_rad == pytest.approx(1.2 * base.c_front_n_per_rad)
    assert scaled.c_rear_n_per_rad == pytest.approx(0.8 * base.c_rear_n_per_rad)
    assert prepare(car).params[dyn.P_AXLE_TIRES] == 0.0


def test_a_car_with_other_tyres_per_axle_corners_as_its_linear_single_track_model():
    car = dataclasses.replace(
        held_out_vehicles()["heldout_sedan_rwd"],
        roll_steer_front_rad_per_rad=0.0,  # the linear model has no roll steer
        roll_steer_rear_rad_per_rad=0.0,
    )
    prepared = prepare(car)
    assert prepared.params[dyn.P_AXLE_TIRES] == 1.0
    model = SingleTrack.from_vehicle(car, TIRE)
    speed = 60.0 / 3.6
    stl = 1.5 / model.lateral_acceleration_gain(speed) * car.stl_per_road_wheel_angle_m_per_rad
    result = simulate(car, Maneuver("ss", "step_steer", 6.0, 60.0, 120.0, stl_amplitude_m=stl))
    tail = slice(-200, None)
    beta_gain, yaw_gain = model.steady_state(float(np.mean(result.u_mps[tail])))
    delta = float(np.mean(result.delta_rad[tail]))
    assert float(np.mean(result.yaw_rate_radps[tail])) == pytest.approx(yaw_gain * delta, rel=0.1)
    assert float(np.mean(result.beta_rad[tail])) == pytest.approx(
        beta_gain * delta, rel=0.1, abs=0.02 * abs(delta)
    )


def test_roll_understeer_lowers_the_steady_yaw_rate_and_mirrors():
    base = dataclasses.replace(
        held_out_vehicles()["heldout_suv_awd"],
        roll_steer_front_rad_per_rad=0.0,
        roll_steer_rear_rad_per_rad=0.0,
    )
    understeer = dataclasses.replace(base, roll_steer_front_rad_per_rad=0.15)
    m = Maneuver("ss", "step_steer", 5.0, 70.0, 150.0, stl_amplitude_m=0.06)
    neutral = simulate(base, m).yaw_rate_radps[-200:].mean()
    left = simulate(understeer, m)
    right = simulate(understeer, dataclasses.replace(m, stl_amplitude_m=-0.06))
    assert left.roll_rad[-1] > 0  # body leans right in a left turn: φ > 0
    assert left.yaw_rate_radps[-200:].mean() < 0.97 * neutral
    np.testing.assert_allclose(left.yaw_rate_radps, -right.yaw_rate_radps, atol=1e-9)


def test_both_sides_turns_each_scripted_run_its_drawn_way_and_changes_nothing_else():
    """``--both-sides``: the same runs (cars, families, speeds, μ, seeds) as the default,
    which opens every scripted manoeuvre to the left; now about half turn right."""
    left, both = fleet(200, seed=4), fleet(200, seed=4, both_sides=True)
    assert all(r.maneuver.side == 1 for r in left)
    for a, b in zip(left, both, strict=True):
        assert a.vehicle == b.vehicle
        assert dataclasses.replace(b.maneuver, side=1) == a.maneuver
    scripted = [r.maneuver for r in both if r.maneuver.family != "cornering"]
    right = sum(m.side == -1 for m in scripted)
    assert 0.35 * len(scripted) < right < 0.65 * len(scripted)
    # Cornering keeps its side in the amplitude's sign, as before.
    assert all(r.maneuver.side == 1 for r in both if r.maneuver.family == "cornering")


def test_both_sides_is_refused_outside_the_fleet_preset(tmp_path, capsys):
    args = ["--preset", "held-out", "--both-sides", "--out", str(tmp_path / "o")]
    assert main(args) == 2
    assert "--both-sides is for --preset fleet" in capsys.readouterr().err
