"""Effective axle characteristics: the UKF's axle curves as the whole car produces them in
steady cornering (lateral load transfer, roll steer), against the tyre-only fit."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sideslip_sim.axle_characteristics import CharacteristicError, steady_cornering_points
from sideslip_sim.axle_tires import axle_tires
from sideslip_sim.tire import load_tire
from sideslip_sim.ukf_params import AxleMagicFormula, fit_axle, ukf_parameters
from sideslip_sim.vehicle import VehicleParams, load_vehicle

AXLES = ("front", "rear")


def _params(vehicle: VehicleParams, axles: str = "effective") -> dict[str, float | str]:
    tire = load_tire(str(vehicle.tire_path()))
    return ukf_parameters(vehicle, *axle_tires(vehicle, tire), axles=axles)


def _curve(params: dict[str, float | str], axle: str) -> AxleMagicFormula:
    return AxleMagicFormula(
        *(float(params[f"{k}_{axle}"]) for k in ("mf_b", "mf_c", "mf_e", "mu_peak"))
    )


def _stiffness(params: dict[str, float | str], axle: str) -> float:
    """B·C·μ_peak: the axle's cornering stiffness over its static load [1/rad]."""
    mf = _curve(params, axle)
    return mf.b * mf.c * mf.mu_peak


def _without_roll_steer(vehicle: VehicleParams) -> VehicleParams:
    return dataclasses.replace(
        vehicle, roll_steer_front_rad_per_rad=0.0, roll_steer_rear_rad_per_rad=0.0
    )


@pytest.mark.parametrize("name", ["paper_sedan", "compact_rwd"])
def test_effective_curves_pass_through_the_steady_cornering_points(name: str) -> None:
    vehicle = load_vehicle(name)
    params = _params(vehicle)
    points = steady_cornering_points(vehicle)
    for axle, alpha, force in (
        ("front", points.alpha_front_rad, points.force_front),
        ("rear", points.alpha_rear_rad, points.force_rear),
    ):
        # The points reach well into the nonlinear range (measured: 0.82 g, 5-6.5° slip).
        assert force.max() > 0.7 and np.degrees(alpha.max()) > 4.0
        residual = _curve(params, axle).force_n(alpha, 1.0) - force
        # Measured: RMS 0.001-0.003, max 0.004-0.013 of the static axle load.
        assert np.sqrt(np.mean(residual**2)) < 0.01
        assert np.max(np.abs(residual)) < 0.03


@pytest.mark.parametrize("name", ["paper_sedan", "compact_rwd"])
def test_without_roll_steer_load_transfer_lowers_the_peak_not_the_stiffness(name: str) -> None:
    # Load transfer is second order in a_y: the small-slip stiffness stays the tyres' (a few
    # % lower, measured 0.97-0.99), the peak drops (measured 4-12 %).
    vehicle = _without_roll_steer(load_vehicle(name))
    effective, tyre = _params(vehicle), _params(vehicle, "tyre")
    for axle in AXLES:
        assert 0.94 < _stiffness(effective, axle) / _stiffness(tyre, axle) <= 1.0
        assert float(effective[f"mu_peak_{axle}"]) < 0.97 * float(tyre[f"mu_peak_{axle}"])
        # The curve's shape factors are the tyre's (module docstring: why).
        assert effective[f"mf_c_{axle}"] == tyre[f"mf_c_{axle}"]
        assert effective[f"mf_e_{axle}"] == tyre[f"mf_e_{axle}"]


def test_a_higher_cg_lowers_both_effective_peaks() -> None:
    vehicle = load_vehicle("compact_rwd")
    higher = dataclasses.replace(vehicle, cg_height_m=vehicle.cg_height_m + 0.15)
    low, high = _params(vehicle), _params(higher)
    for axle in AXLES:
        assert float(high[f"mu_peak_{axle}"]) < 0.97 * float(low[f"mu_peak_{axle}"])


def test_rear_roll_understeer_stiffens_the_effective_rear_axle() -> None:
    # Roll understeer at the rear steers the rear wheels into the turn's outside: more rear
    # slip for the same single-track slip angle, so a stiffer rear axle as the model sees it.
    vehicle = _without_roll_steer(load_vehicle("compact_rwd"))
    steered = dataclasses.replace(vehicle, roll_steer_rear_rad_per_rad=0.1)
    plain, more = _params(vehicle), _params(steered)
    assert _stiffness(more, "rear") > 1.04 * _stiffness(plain, "rear")
    assert _stiffness(more, "front") == pytest.approx(_stiffness(plain, "front"), rel=0.02)


def test_tyre_axles_are_the_pure_tyre_fit() -> None:
    vehicle = load_vehicle("paper_sedan")
    tire = load_tire(str(vehicle.tire_path()))
    params = _params(vehicle, "tyre")
    mf = fit_axle(tire, vehicle.static_axle_load_rear_n)
    assert float(params["mf_b_rear"]) == pytest.approx(mf.b, rel=1e-4)
    assert float(params["mu_peak_rear"]) == pytest.approx(mf.mu_peak, rel=1e-4)


def test_unknown_axle_source_is_refused_by_name() -> None:
    vehicle = load_vehicle("paper_sedan")
    tire = load_tire(str(vehicle.tire_path()))
    with pytest.raises(ValueError, match="axles must be one of"):
        ukf_parameters(vehicle, tire, tire, axles="measured")


def test_no_steady_cornering_is_a_clear_error() -> None:
    with pytest.raises(CharacteristicError, match="no steady cornering"):
        steady_cornering_points(load_vehicle("paper_sedan"), ay_fractions=())


def test_effective_axles_refuse_tyres_other_than_the_cars_own() -> None:
    vehicle = load_vehicle("paper_sedan")
    tire = load_tire(str(vehicle.tire_path()))
    slippery = tire.with_values(LMUY=0.8 * tire["LMUY"])
    with pytest.raises(ValueError, match="own tyres"):
        ukf_parameters(vehicle, tire, slippery)
