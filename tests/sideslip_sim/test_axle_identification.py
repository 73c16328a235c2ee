"""The UKF's axle curves identified from labelled recordings (sideslip_sim.axle_identification)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sideslip_sim.axle_identification import (
    IdentificationError,
    IdentificationSettings,
    RecordedRun,
    identify_axles,
)
from sideslip_sim.axle_tires import axle_tires
from sideslip_sim.presets import fleet_runs
from sideslip_sim.simulate import simulate
from sideslip_sim.tire import load_tire
from sideslip_sim.ukf_params import ukf_parameters
from sideslip_sim.vehicle import load_vehicle

# The paper's sensor noise (sideslip_msgs_py.channels): speed, acceleration, yaw rate, rack.
NOISE = (1.0 / 3.6, 0.1, math.radians(0.2), 1.0e-3)


@pytest.fixture(scope="module")
def car_and_file():
    car = load_vehicle("compact_rwd")
    return car, ukf_parameters(car, *axle_tires(car, load_tire(str(car.tire_path()))))


def recordings(car, count: int = 12, seed: int = 5) -> list[RecordedRun]:
    """Fleet-style runs of ``car`` (about 2 min, μ 0.3-1.0) with the paper's noise and
    the exact β as the reference."""
    rng = np.random.default_rng(seed)
    out = []
    for vr in fleet_runs([car] * (count // 4), count, seed):
        s = simulate(vr.vehicle, vr.maneuver)

        def noisy(x: np.ndarray, sd: float, s=s) -> np.ndarray:
            return x + rng.normal(0.0, sd, s.t_s.size)

        out.append(
            RecordedRun(
                vr.maneuver.name,
                s.t_s,
                noisy(s.u_mps, NOISE[0]),
                np.arctan2(s.v_mps, s.u_mps),
                noisy(s.yaw_rate_radps, NOISE[2]),
                noisy(s.ay_mps2, NOISE[1]),
                noisy(s.ax_mps2, NOISE[1]),
                noisy(s.stl_m, NOISE[3]),
            )
        )
    return out


def test_identification_recovers_the_cars_effective_cornering_stiffness(car_and_file):
    """Started 30 % too stiff in front and 25 % too soft at the rear (a described car's
    typical misses), two minutes of noisy driving bring both axles' B within 4 % of the
    car's effective axle characteristic (from its steady cornering, a separate path)."""
    car, true = car_and_file
    wrong = dict(true, mf_b_front=1.3 * true["mf_b_front"], mf_b_rear=0.75 * true["mf_b_rear"])
    found = identify_axles(recordings(car), wrong)
    assert found.params["mf_b_front"] / true["mf_b_front"] == pytest.approx(1.0, abs=0.04)
    assert found.params["mf_b_rear"] / true["mf_b_rear"] == pytest.approx(1.0, abs=0.04)
    assert found.stiffness_ratio_front == pytest.approx(1 / 1.3, abs=0.04)
    assert found.stiffness_ratio_rear == pytest.approx(1 / 0.75, abs=0.06)
    # Only B moves: the rest of the file is the start's.
    unchanged = {k: v for k, v in wrong.items() if k not in ("mf_b_front", "mf_b_rear")}
    assert {k: found.params[k] for k in unchanged} == unchanged


def test_mirrored_recordings_identify_the_same_stiffness(car_and_file):
    """A car is symmetric: the same driving mirrored left-right (every lateral channel and
    β negated) is the same axle curve."""
    car, true = car_and_file
    runs = recordings(car, count=8, seed=11)
    mirrored = [
        dataclasses.replace(
            r,
            beta_rad=-r.beta_rad,
            yaw_rate_radps=-r.yaw_rate_radps,
            ay_mps2=-r.ay_mps2,
            stl_m=-r.stl_m,
        )
        for r in runs
    ]
    a, b = identify_axles(runs, true), identify_axles(mirrored, true)
    assert b.params["mf_b_front"] == pytest.approx(a.params["mf_b_front"], rel=1e-6)
    assert b.params["mf_b_rear"] == pytest.approx(a.params["mf_b_rear"], rel=1e-6)


def test_straight_driving_is_refused_asking_for_cornering(car_and_file):
    _car, true = car_and_file
    n = 4000
    t = np.arange(n) * 0.0025
    straight = RecordedRun(
        "straight", t, np.full(n, 20.0), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n),
        np.zeros(n),
    )  # fmt: skip
    with pytest.raises(IdentificationError, match="record some cornering"):
        identify_axles([straight], true)


def test_too_little_driving_is_refused_naming_the_points_needed(car_and_file):
    car, true = car_and_file
    short = recordings(car, count=4)[:1]
    settings = IdentificationSettings(min_points=10**6)
    with pytest.raises(IdentificationError, match="at least 1000000 needed"):
        identify_axles(short, true, settings)


def test_a_quasi_steady_limit_uses_fewer_points(car_and_file):
    car, true = car_and_file
    runs = recordings(car, count=8)
    every = identify_axles(runs, true, IdentificationSettings(max_yaw_accel_radps2=math.inf))
    steady = identify_axles(runs, true, IdentificationSettings(max_yaw_accel_radps2=0.05))
    assert steady.points < every.points


def test_a_recording_too_slow_for_the_filter_is_refused_naming_its_rate(car_and_file):
    _car, true = car_and_file
    run = recordings(load_vehicle("compact_rwd"), count=4)[0]
    every = slice(None, None, 100)  # 400 Hz -> 4 Hz
    slow = RecordedRun(
        "slow", run.t_s[every], run.u_mps[every], run.beta_rad[every],
        run.yaw_rate_radps[every], run.ay_mps2[every], run.ax_mps2[every], run.stl_m[every],
    )  # fmt: skip
    with pytest.raises(IdentificationError, match="slow: recorded at 4 Hz"):
        identify_axles([slow], true)
