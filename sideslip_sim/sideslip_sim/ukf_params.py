"""The estimator's ``ukf`` parameters: nominal vehicle numbers and one Magic Formula per axle.

The UKF back-end (``sideslip_estimator.backends.ukf``) runs a nonlinear single-track
model whose axle lateral force is

    F_y(α) = D sin(C atan(B α − E (B α − atan(B α)))),   D = μ_peak F_z,axle,

with α the axle slip angle [rad] (not tan α) and F_z,axle the static axle load. The
estimator does not import the simulator (DESIGN.md), so it reads B, C, E and μ_peak from
a YAML file; this module fits them and writes that file.

Two fits, both least squares (``scipy.optimize.least_squares``, forces relative to the
axle load):

- ``tyre``: the formula fitted to the full tyre model's pure lateral force of the axle's
  two tyres at their static load (κ = 0, road μ scale 1), over α = 0-15° in 0.1° steps.
  On the shipped tyre the MF 5.2 curve *is* a Magic Formula in tan α, so the fit in α is
  close to exact (max error well below 1 % of the peak; tested).
- ``effective`` (the default): C and E from that fit, B and μ_peak fitted to the axle's
  force against its single-track slip angle in the whole car's steady cornering, which
  includes lateral load transfer and roll steer (:mod:`sideslip_sim.axle_characteristics`).
  On the 100 runs of the validation fleet (25 cars) the UKF's pooled MAE fell from
  0.141° to 0.104° with it (better on 94 runs; docs/training.md, "The UKF's axles").

Besides the fit: the nominal mass, yaw inertia, geometry, CG height (longitudinal load
transfer) and steering ratio of the vehicle file, and each axle's lateral relaxation
length σ_α at the static tyre load (MF 5.2's PTY1/PTY2; the UKF's tyre lag).

Each axle has its own tyre (per-axle cornering stiffness and friction scaling), hence one
:class:`~sideslip_sim.tire.TireParams` per axle; the CLI passes the vehicle's tyre file
scaled per axle (:func:`~sideslip_sim.axle_tires.axle_tires`).
``python -m sideslip_sim.ukf_params VEHICLE`` prints the file.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np

from sideslip_sim.tire import TireParams
from sideslip_sim.tire_forces import combined_forces, relaxation_lengths
from sideslip_sim.vehicle import VehicleParams

FIT_MAX_SLIP_DEG = 15.0
FIT_STEP_DEG = 0.1


@dataclass(frozen=True)
class AxleMagicFormula:
    """F_y(α) = μ_peak F_z sin(C atan(B α − E (B α − atan(B α)))) of one axle [N, rad]."""

    b: float
    c: float
    e: float
    mu_peak: float

    def force_n(self, alpha_rad: np.ndarray, fz_axle_n: float) -> np.ndarray:
        x = self.b * np.asarray(alpha_rad, dtype=float)
        return (
            self.mu_peak * fz_axle_n * np.sin(self.c * np.arctan(x - self.e * (x - np.arctan(x))))
        )


def slip_angles_rad(
    max_deg: float = FIT_MAX_SLIP_DEG, step_deg: float = FIT_STEP_DEG
) -> np.ndarray:
    """The fit's slip angles: 0 to ``max_deg`` in ``step_deg`` steps [rad]."""
    return np.radians(np.arange(0.0, max_deg + 0.5 * step_deg, step_deg))


def axle_lateral_force_n(tire: TireParams, fz_axle_n: float, alpha_rad: np.ndarray) -> np.ndarray:
    """Pure lateral force [N] of the axle's two tyres, each at half of ``fz_axle_n``."""
    coef = tire.coefficients()
    fz_tire = 0.5 * fz_axle_n
    return np.array(
        [2.0 * combined_forces(coef, fz_tire, 0.0, math.tan(a), 1.0)[1] for a in alpha_rad]
    )


def fit_axle(tire: TireParams, fz_axle_n: float) -> AxleMagicFormula:
    """Least-squares Magic Formula of the axle's force curve at ``fz_axle_n`` (see module)."""
    # scipy only here: the simulator itself does not need it.
    from scipy.optimize import least_squares

    alpha = slip_angles_rad()
    target = axle_lateral_force_n(tire, fz_axle_n, alpha) / fz_axle_n

    def residual(p: np.ndarray) -> np.ndarray:
        return AxleMagicFormula(*p).force_n(alpha, 1.0) - target

    # Start: peak from the data, B from the initial slope with a typical C.
    peak = float(np.max(target))
    slope = float(target[1] / alpha[1])
    c0 = 1.3
    start = np.array([slope / (c0 * peak), c0, 0.0, peak])
    fit = least_squares(
        residual,
        start,
        bounds=([0.1, 0.5, -10.0, 0.05], [100.0, 2.0, 1.0, 5.0]),
        x_scale=np.array([1.0, 0.1, 0.1, 0.1]),
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
    )
    if not fit.success:  # pragma: no cover - least_squares converges on any MF-like curve
        raise ValueError(f"Magic Formula fit failed: {fit.message}")
    return AxleMagicFormula(*(float(v) for v in fit.x))


def fit_effective(
    alpha_rad: np.ndarray, force: np.ndarray, tyre_fit: AxleMagicFormula
) -> AxleMagicFormula:
    """B and μ_peak fitted to an axle's quasi-steady points (force over static axle load
    against single-track slip angle, :mod:`sideslip_sim.axle_characteristics`), C and E
    kept from ``tyre_fit`` (why: that module)."""
    from scipy.optimize import least_squares

    c, e = tyre_fit.c, tyre_fit.e

    def residual(p: np.ndarray) -> np.ndarray:
        return AxleMagicFormula(p[0], c, e, p[1]).force_n(alpha_rad, 1.0) - force

    fit = least_squares(
        residual,
        np.array([tyre_fit.b, tyre_fit.mu_peak]),
        bounds=([0.1, 0.05], [100.0, 5.0]),
        xtol=1e-12,
        ftol=1e-12,
    )
    if not fit.success:  # pragma: no cover - two parameters of a monotone curve
        raise ValueError(f"effective axle fit failed: {fit.message}")
    return AxleMagicFormula(float(fit.x[0]), c, e, float(fit.x[1]))


AXLE_SOURCES = ("effective", "tyre")
"""How the axle curves are made: ``effective`` (the default), the full car's quasi-steady
axle characteristics (:mod:`sideslip_sim.axle_characteristics`); ``tyre``, the pure curve
of the axle's two tyres at static load (:func:`fit_axle`), as before 2026-12-02."""


def ukf_parameters(
    vehicle: VehicleParams,
    tire_front: TireParams,
    tire_rear: TireParams,
    *,
    axles: str = "effective",
) -> dict[str, float | str]:
    """The estimator's ``ukf`` back-end parameters (YAML keys) for this vehicle, with axle
    curves made as ``axles`` says (:data:`AXLE_SOURCES`)."""
    if axles not in AXLE_SOURCES:
        raise ValueError(f"axles must be one of {AXLE_SOURCES}, got {axles!r}")
    front = fit_axle(tire_front, vehicle.static_axle_load_front_n)
    rear = fit_axle(tire_rear, vehicle.static_axle_load_rear_n)
    if axles == "effective":
        from sideslip_sim.axle_characteristics import steady_cornering_points
        from sideslip_sim.axle_tires import axle_tires
        from sideslip_sim.tire import load_tire

        # The full model corners on the car's own tyres: other tyres would give a file
        # whose shape is one tyre's and whose stiffness and peak are another's.
        own = axle_tires(vehicle, load_tire(str(vehicle.tire_path())))
        if (tire_front.values, tire_rear.values) != (own[0].values, own[1].values):
            raise ValueError(
                f"{vehicle.name}: effective axles are the car's own tyres in cornering; "
                "for other tyres use axles='tyre'"
            )
        points = steady_cornering_points(vehicle)
        front = fit_effective(points.alpha_front_rad, points.force_front, front)
        rear = fit_effective(points.alpha_rear_rad, points.force_rear, rear)
    out: dict[str, float | str] = {
        "name": vehicle.name,
        "mass_kg": vehicle.mass_kg,
        "yaw_inertia_kgm2": vehicle.yaw_inertia_kgm2,
        "cg_to_front_axle_m": vehicle.cg_to_front_axle_m,
        "cg_to_rear_axle_m": vehicle.cg_to_rear_axle_m,
        "cg_height_m": vehicle.cg_height_m,
        "stl_per_road_wheel_angle_m_per_rad": vehicle.stl_per_road_wheel_angle_m_per_rad,
    }
    for axle, mf in (("front", front), ("rear", rear)):
        # Five significant digits: the fit itself is good to ~1e-3 of the peak.
        out[f"mf_b_{axle}"] = float(f"{mf.b:.5g}")
        out[f"mf_c_{axle}"] = float(f"{mf.c:.5g}")
        out[f"mf_e_{axle}"] = float(f"{mf.e:.5g}")
        out[f"mu_peak_{axle}"] = float(f"{mf.mu_peak:.5g}")
    for axle, tire, fz in (
        ("front", tire_front, vehicle.static_axle_load_front_n),
        ("rear", tire_rear, vehicle.static_axle_load_rear_n),
    ):
        sigma_alpha = relaxation_lengths(tire.coefficients(), 0.5 * fz)[1]
        out[f"relaxation_length_{axle}_m"] = round(float(sigma_alpha), 4)
    return out


def _described(path: str) -> VehicleParams:
    """The full car of a description file (:mod:`sideslip_sim.described_car`)."""
    from pathlib import Path

    import yaml

    from sideslip_sim.described_car import described_from_mapping

    data = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a mapping of parameters")
    return described_from_mapping(data, path, name=str(data.get("name", Path(path).stem)))


def main(argv: list[str] | None = None) -> int:
    """Print the UKF observer parameters of a vehicle as YAML."""
    import argparse

    import yaml

    from sideslip_sim.axle_tires import axle_tires
    from sideslip_sim.tire import load_tire
    from sideslip_sim.vehicle import VehicleFileError, load_vehicle

    parser = argparse.ArgumentParser(
        prog="python -m sideslip_sim.ukf_params",
        description="Print the estimator's ukf parameters (YAML) for a vehicle: nominal "
        "mass, inertia and geometry, and per axle a Magic Formula (B, C, E, μ_peak) of the "
        "axle's lateral force against its single-track slip angle (see --axles).",
    )
    parser.add_argument(
        "vehicle",
        help="shipped vehicle name or path to a vehicle YAML; with --description, a short "
        "description (mass_kg, wheelbase_m, cg_to_front_axle_m, cg_height_m, track_m, "
        "stl_per_road_wheel_angle_m_per_rad, tire_rolling_radius_m; optionally "
        "drive_layout and name)",
    )
    parser.add_argument(
        "--description",
        action="store_true",
        help="VEHICLE is a short description: what is unknown (inertia, tyres, balance) "
        "takes the fleet's typical values (sideslip_sim.described_car)",
    )
    parser.add_argument(
        "--axles",
        choices=AXLE_SOURCES,
        default="effective",
        help="effective (default): each axle's curve as the whole car produces it in "
        "steady cornering (lateral load transfer and roll steer included; "
        "sideslip_sim.axle_characteristics); tyre: the pure curve of the axle's two tyres "
        "at static load (the files written before 2026-12-02)",
    )
    args = parser.parse_args(argv)
    try:
        vehicle = _described(args.vehicle) if args.description else load_vehicle(args.vehicle)
        tire = load_tire(str(vehicle.tire_path()))
        params = ukf_parameters(vehicle, *axle_tires(vehicle, tire), axles=args.axles)
        if args.description:
            # The tyres are the fleet's typical ones: a model reading the UKF publishes its
            # σ for described files with this file (backends.ukf_model.AXLES_FROM).
            params["axles_from"] = "description"
    except (VehicleFileError, OSError, ValueError, yaml.YAMLError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    command = " ".join(["python -m sideslip_sim.ukf_params", *(argv or sys.argv[1:])])
    print(f"# ukf parameters of {vehicle.name} ({command})")
    print("# Axle lateral force F_y = mu_peak*F_z*sin(C*atan(B*a - E*(B*a - atan(B*a)))),")
    print(
        "# a = slip angle [rad], F_z = static axle load [N]; "
        + (
            "fitted to the tyre model."
            if args.axles == "tyre"
            else "B, mu_peak fitted to the full car's\n# steady cornering (load transfer, "
            "roll steer), C, E to the tyre model."
        )
    )
    print(yaml.safe_dump(params, sort_keys=False), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
