"""The ukf back-end's parameter export: Magic Formula fits per axle, the shipped files and
the CLI that writes them."""

from __future__ import annotations

from importlib import resources

import numpy as np
import pytest
import yaml

from sideslip_estimator.backends import UkfParams
from sideslip_sim.single_track import SingleTrack
from sideslip_sim.tire import load_tire
from sideslip_sim.tire_forces import relaxation_lengths
from sideslip_sim.ukf_params import (
    axle_lateral_force_n,
    fit_axle,
    main,
    slip_angles_rad,
    ukf_parameters,
)
from sideslip_sim.vehicle import load_vehicle, shipped_vehicles

SHIPPED = resources.files("sideslip_estimator").joinpath("data/ukf")


@pytest.mark.parametrize("vehicle", shipped_vehicles())
@pytest.mark.parametrize("axle", ["front", "rear"])
def test_fitted_magic_formula_reproduces_the_axle_force_curve(vehicle: str, axle: str) -> None:
    v = load_vehicle(vehicle)
    tire = load_tire(str(v.tire_path()))
    fz = v.static_axle_load_front_n if axle == "front" else v.static_axle_load_rear_n
    mf = fit_axle(tire, fz)
    # Over 0-15° (the fit range) and beyond it to 20° (extrapolation a saturating car meets).
    alpha = np.radians(np.linspace(0.0, 20.0, 201))
    target = axle_lateral_force_n(tire, fz, alpha)
    err = np.abs(mf.force_n(alpha, fz) - target)
    assert np.max(err) <= 0.01 * np.max(target)  # measured: 4e-5 of the peak
    # The initial slope is the linear single-track model's axle cornering stiffness.
    model = SingleTrack.from_vehicle(v, tire)
    stiffness = model.c_front_n_per_rad if axle == "front" else model.c_rear_n_per_rad
    assert mf.b * mf.c * mf.mu_peak * fz == pytest.approx(stiffness, rel=0.005)


def test_tyre_fit_follows_the_tyre_it_is_given() -> None:
    # One tyre per axle: a tyre with 20 % less peak friction gives a 20 % lower μ_peak and
    # the same cornering stiffness (MF 5.2's LMUY keeps B·C·D).
    v = load_vehicle("paper_sedan")
    tire = load_tire(str(v.tire_path()))
    slippery = tire.with_values(LMUY=0.8 * tire["LMUY"])
    params = ukf_parameters(v, tire, slippery, axles="tyre")
    same = ukf_parameters(v, tire, tire, axles="tyre")
    assert params["mu_peak_front"] == same["mu_peak_front"]
    assert params["mu_peak_rear"] == pytest.approx(0.8 * float(same["mu_peak_rear"]), rel=2e-3)
    bcd = {
        k: float(p["mf_b_rear"]) * float(p["mf_c_rear"]) * float(p["mu_peak_rear"])
        for k, p in (("slippery", params), ("same", same))
    }
    assert bcd["slippery"] == pytest.approx(bcd["same"], rel=2e-3)


def test_slip_angles_span_zero_to_fifteen_degrees() -> None:
    alpha = np.degrees(slip_angles_rad())
    assert alpha[0] == 0.0 and alpha[-1] == pytest.approx(15.0) and len(alpha) == 151


@pytest.mark.parametrize("vehicle", shipped_vehicles())
def test_shipped_ukf_yaml_equals_the_export_from_the_vehicle_file(vehicle: str) -> None:
    v = load_vehicle(vehicle)
    tire = load_tire(str(v.tire_path()))
    exported = ukf_parameters(v, tire, tire)
    shipped = yaml.safe_load(SHIPPED.joinpath(f"{vehicle}.yaml").read_text())
    assert shipped == exported
    assert UkfParams.load(vehicle) == UkfParams.from_mapping(exported, "export")
    coef = tire.coefficients()
    assert exported["relaxation_length_rear_m"] == pytest.approx(
        relaxation_lengths(coef, 0.5 * v.static_axle_load_rear_n)[1], abs=1e-4
    )


def test_a_ukf_file_is_shipped_for_every_shipped_vehicle() -> None:
    names = sorted(p.name.removesuffix(".yaml") for p in SHIPPED.iterdir())
    assert names == shipped_vehicles()


def test_cli_prints_the_yaml_with_the_command_in_its_header(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["compact_rwd"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("# ukf parameters of compact_rwd (python -m sideslip_sim.ukf_params")
    assert yaml.safe_load(out) == yaml.safe_load(SHIPPED.joinpath("compact_rwd.yaml").read_text())


def test_cli_unknown_vehicle_is_one_line_and_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["hovercraft"]) == 2
    err = capsys.readouterr().err
    assert "hovercraft" in err and err.count("\n") == 1


def test_cli_axles_tyre_prints_the_tyre_only_fit(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["compact_rwd", "--axles", "tyre"]) == 0
    out = capsys.readouterr().out
    assert "--axles tyre" in out.splitlines()[0] and "fitted to the tyre model." in out
    v = load_vehicle("compact_rwd")
    tire = load_tire(str(v.tire_path()))
    assert yaml.safe_load(out) == ukf_parameters(v, tire, tire, axles="tyre")
    assert yaml.safe_load(out) != yaml.safe_load(SHIPPED.joinpath("compact_rwd.yaml").read_text())
