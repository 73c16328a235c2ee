"""Manoeuvres and presets: names, ranges, the paper grids and reproducible draws."""

from __future__ import annotations

import numpy as np
import pytest

from sideslip_sim.maneuvers import Maneuver, ManeuverError, build_program
from sideslip_sim.presets import TABLE3, PresetError, paper_test, paper_train, preset, randomized
from sideslip_sim.simulate import DT_S, prepare
from sideslip_sim.vehicle import load_vehicle


def test_unknown_family_is_rejected_with_the_known_ones():
    with pytest.raises(ManeuverError, match="unknown family 'slalom'"):
        Maneuver("x", "slalom", 5.0, 50.0, 0.0)


@pytest.mark.parametrize(
    ("field", "value"),
    [("duration_s", 0.0), ("speed_kmh", -1.0), ("mu", 0.0), ("payload_kg", -1.0)],
)
def test_out_of_range_values_are_rejected(field, value):
    kwargs = {
        "name": "x",
        "family": "straight",
        "duration_s": 5.0,
        "speed_kmh": 50.0,
        "torque_nm": 0.0,
        field: value,
    }
    with pytest.raises(ManeuverError, match=field):
        Maneuver(**kwargs)


def test_paper_train_covers_every_family_and_listed_value_of_table3():
    runs = paper_train()
    families = {m.family for m in runs}
    assert families == set(TABLE3)
    for family, spec in TABLE3.items():
        subset = [m for m in runs if m.family == family]
        assert {m.speed_kmh for m in subset} == set(spec["speed_kmh"]), family
        assert {m.torque_nm for m in subset} == set(spec["torque_nm"]), family
        assert {m.duration_s for m in subset} == {float(t) for t in spec["time_s"]}, family
        if "stl_m" in spec:
            assert {abs(m.stl_amplitude_m) for m in subset} == set(spec["stl_m"]), family
            # Both steering directions are present.
            assert {np.sign(m.stl_amplitude_m) for m in subset} == {-1.0, 1.0}, family
    samples = sum(round(m.duration_s / DT_S) for m in runs)
    assert samples >= 100_000
    assert len({m.name for m in runs}) == len(runs)


def test_paper_test_is_table4():
    runs = paper_test()
    assert [m.name for m in runs] == ["scen1", "scen2", "scen3", "scen4"]
    assert [(m.speed_kmh, m.torque_nm, m.duration_s) for m in runs] == [
        (80.0, 500.0, 9.5),
        (90.0, 500.0, 10.5),
        (75.0, 500.0, 9.5),
        (75.0, 500.0, 8.0),
    ]
    train_seeds = {m.seed for m in paper_train() if m.family == "random_steer"}
    assert not train_seeds & {m.seed for m in runs}


def test_randomized_preset_is_reproducible_and_spans_its_ranges():
    a, b = randomized(200, seed=7), randomized(200, seed=7)
    assert a == b
    assert randomized(200, seed=8) != a
    mus = np.array([m.mu for m in a])
    assert mus.min() >= 0.3 and mus.max() <= 1.0 and np.ptp(mus) > 0.5
    assert len({m.family for m in a}) >= 5
    assert max(m.payload_kg for m in a) > 100.0


def test_unknown_preset_is_rejected_with_the_known_ones():
    with pytest.raises(PresetError, match="paper-train"):
        preset("paper-trian")


def test_programs_have_one_input_per_400hz_step():
    vehicle = load_vehicle("paper_sedan")
    prepared = prepare(vehicle)
    for m in paper_test():
        program = build_program(m, vehicle, prepared.single_track, DT_S)
        n = round(m.duration_s / DT_S)
        assert program.stl_open_m.shape == program.use_driver.shape == (n,)
        assert np.all(np.isfinite(program.stl_open_m))


def test_auto_amplitude_keeps_steering_within_the_lock():
    vehicle = load_vehicle("paper_sedan")
    prepared = prepare(vehicle)
    m = Maneuver("slow", "random_steer", 5.0, 5.0, 0.0, seed=1, ay_fraction=1.0)
    program = build_program(m, vehicle, prepared.single_track, DT_S)
    lock_stl = vehicle.max_road_wheel_angle_rad * vehicle.stl_per_road_wheel_angle_m_per_rad
    assert np.max(np.abs(program.stl_open_m)) <= lock_stl + 1e-12
