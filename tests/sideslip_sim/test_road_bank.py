"""A banked road (``Maneuver.bank_pct``, ``sideslip-generate --bank``): gravity's share in
the road plane pulls the car downhill and leans the body, the kinematics the estimators
rest on still hold, a mirrored run on the mirrored road is the mirror image, and an IMU
tilted with the body reads the slope."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sideslip_msgs_py.bag import read_bag
from sideslip_sim.generate_cli import main
from sideslip_sim.imu_mounting import ImuMounting, mounted_accelerations
from sideslip_sim.maneuvers import BANK_RAMP_S, Maneuver, ManeuverError
from sideslip_sim.presets import PresetError, on_random_banks, vehicle_preset
from sideslip_sim.simulate import simulate
from sideslip_sim.stream import ManeuverSpec, select_runs
from sideslip_sim.vehicle import GRAVITY_MPS2, load_vehicle


@pytest.fixture(scope="module")
def sedan():
    return load_vehicle("paper_sedan")


@pytest.fixture(scope="module")
def straight_on_bank(sedan):
    return simulate(sedan, Maneuver("bank", "straight", 6.0, 80.0, 0.0, bank_pct=3.0))


def test_a_level_road_adds_no_gravity(sedan):
    run = simulate(sedan, Maneuver("flat", "straight", 2.0, 60.0, 0.0))
    assert not run.gravity_x_mps2.any() and not run.gravity_y_mps2.any()
    assert not run.v_mps.any() and not run.roll_rad.any()  # straight stays straight


def test_the_slope_is_ramped_in_over_the_first_second(straight_on_bank):
    run = straight_on_bank
    g_y = run.gravity_y_mps2
    assert g_y[0] == 0.0
    full = GRAVITY_MPS2 * math.sin(math.atan(0.03))
    after = run.t_s >= BANK_RAMP_S
    # Falling to the right: pulls towards −y. The car turns downhill a little, so gravity's
    # share in y is cos ψ of the full one.
    np.testing.assert_allclose(g_y[after], -full * np.cos(run.psi_rad[after]), rtol=1e-12)
    assert np.all(np.diff(np.abs(g_y[run.t_s < BANK_RAMP_S])) >= 0.0)


def test_a_banked_road_pulls_the_car_downhill_and_leans_the_body(straight_on_bank):
    run = straight_on_bank
    assert run.y_m[-1] < -0.5  # drifts right, down the slope, without steering
    assert run.psi_rad[-1] < 0.0  # and turns downhill
    assert run.roll_rad[-1] > 0.0  # φ > 0: the body leans to the right, downhill
    # The downhill (right) wheels carry more.
    fz = run.fz_n[-1]
    assert fz[1] + fz[3] > fz[0] + fz[2]


def test_the_kinematics_the_estimators_rest_on_hold_on_a_bank(sedan):
    step = Maneuver("s", "step_steer", 5.0, 70.0, 0.0, stl_amplitude_m=0.03, bank_pct=5.0)
    run = simulate(sedan, step)
    # The level IMU reads the CG's acceleration: v̇ = a_y − r·u, gravity or not.
    v_dot = np.gradient(run.v_mps, run.t_s)
    residual = v_dot - (run.ay_mps2 - run.yaw_rate_radps * run.u_mps)
    assert np.abs(residual[5:-5]).max() < 0.02
    # ... while the tyres carry a_y − g_y: a different signal on a slope.
    assert np.abs(run.gravity_y_mps2).max() > 0.4


def test_a_mirrored_run_on_the_mirrored_road_is_the_mirror_image(sedan):
    m = Maneuver("sine", "sine_steer", 4.0, 60.0, 0.0, stl_amplitude_m=0.02, bank_pct=4.0)
    run = simulate(sedan, m)
    mirrored = simulate(sedan, dataclasses.replace(m, side=-1))
    for name in ("v_mps", "yaw_rate_radps", "ay_mps2", "roll_rad", "y_m", "gravity_y_mps2"):
        np.testing.assert_allclose(
            getattr(mirrored, name), -getattr(run, name), atol=1e-9, err_msg=name
        )
    for name in ("u_mps", "ax_mps2", "pitch_rad", "gravity_x_mps2"):
        np.testing.assert_allclose(getattr(mirrored, name), getattr(run, name), atol=1e-9)


def test_an_imu_tilted_with_the_road_reads_the_slope():
    # A car standing on a 3 % crossfall, body level on its springs: no acceleration, and
    # the body-frame accelerometer reads gravity's share in the road plane.
    t = np.linspace(0.0, 1.0, 5)
    zeros = np.zeros_like(t)
    g_y = -GRAVITY_MPS2 * math.sin(math.atan(0.03))
    f_x, f_y = mounted_accelerations(
        ImuMounting(frame="body"), t, zeros, zeros, zeros, zeros, zeros, 0.0, g_y
    )
    np.testing.assert_allclose(f_y, -g_y)
    np.testing.assert_allclose(f_x, 0.0)
    # The level IMU (the contract's) reads the CG's acceleration: none.
    _, level = mounted_accelerations(ImuMounting(), t, zeros, zeros, zeros, zeros, zeros, 0.0, g_y)
    np.testing.assert_allclose(level, 0.0)


@pytest.mark.parametrize("bank", [10.5, -12.0, math.nan])
def test_a_crossfall_beyond_ten_percent_is_refused_naming_it(bank):
    with pytest.raises(ManeuverError, match="bank_pct"):
        Maneuver("x", "straight", 1.0, 50.0, 0.0, bank_pct=bank)


def test_generate_puts_every_run_on_a_road_falling_to_the_right(tmp_path):
    out = tmp_path / "bank"
    code = main(
        ["--preset", "paper-test", "--out", str(out), "--bank", "2.5", "--jobs", "1", "--quiet"]
    )
    assert code == 0
    bags = sorted(p for p in out.iterdir() if p.is_dir())
    assert bags
    for bag in bags:
        maneuver = read_bag(bag).run_metadata["maneuver"]
        assert maneuver["bank_pct"] == 2.5 * maneuver["side"]


def test_generate_refuses_a_crossfall_beyond_ten_percent(tmp_path, capsys):
    assert main(["--preset", "paper-test", "--out", str(tmp_path / "o"), "--bank", "15"]) == 2
    assert "bank_pct" in capsys.readouterr().err


def test_the_sim_nodes_family_runs_take_their_crossfall_from_the_parameters():
    (run,) = select_runs("straight", spec=ManeuverSpec(bank_pct=2.0))
    assert run.bank_pct == 2.0


def test_random_crossfalls_are_seeded_within_the_spread_and_change_nothing_else():
    runs = vehicle_preset("fleet", seed=1, count=40)
    banked = on_random_banks(runs, 4.0, seed=1)
    again = on_random_banks(runs, 4.0, seed=1)
    other = on_random_banks(runs, 4.0, seed=2)
    banks = np.array([r.maneuver.bank_pct for r in banked])
    assert np.all(np.abs(banks) <= 4.0)
    assert (banks > 0).any() and (banks < 0).any()  # both ways, not one drain side
    assert banks.tolist() == [r.maneuver.bank_pct for r in again]
    assert banks.tolist() != [r.maneuver.bank_pct for r in other]
    for plain, tilted in zip(runs, banked, strict=True):
        assert tilted.vehicle == plain.vehicle
        assert dataclasses.replace(tilted.maneuver, bank_pct=0.0) == plain.maneuver


@pytest.mark.parametrize("spread", [0.0, -1.0, 10.5, math.nan])
def test_a_crossfall_spread_outside_ten_percent_is_refused(spread):
    with pytest.raises(PresetError, match="bank spread"):
        on_random_banks(vehicle_preset("fleet", seed=1, count=4), spread, seed=1)


def test_generate_draws_each_runs_crossfall_and_refuses_it_beside_a_fixed_one(tmp_path, capsys):
    out = tmp_path / "spread"
    argv = ["--preset", "fleet", "--count", "4", "--seed", "3", "--out", str(out)]
    assert main([*argv, "--bank-spread", "3", "--jobs", "1", "--quiet"]) == 0
    banks = [read_bag(b).run_metadata["maneuver"]["bank_pct"] for b in sorted(out.iterdir())
             if b.is_dir()]  # fmt: skip
    assert len(banks) == 4 and len(set(banks)) == 4
    assert all(abs(b) <= 3.0 for b in banks)
    assert main([*argv, "--bank", "2", "--bank-spread", "3", "--force"]) == 2
    assert "--bank-spread" in capsys.readouterr().err
