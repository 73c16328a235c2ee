"""Linear single-track (bicycle) model built from the same vehicle and tyre parameters.

It serves three purposes: a reference for the full model's physics tests, the
understeer gradient the path-following driver feeds forward, and the steering scale
that keeps manoeuvre amplitudes physically sensible at each speed.

Axle cornering stiffness = 2 × the axle tyre's dFy/dα at the static corner load (N/rad),
with the vehicle's per-axle tyre scaling applied (see axle_tires).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from sideslip_sim.axle_tires import axle_tires
from sideslip_sim.tire import TireParams
from sideslip_sim.tire_forces import cornering_stiffness
from sideslip_sim.vehicle import VehicleParams


@dataclass(frozen=True)
class SingleTrack:
    """Linear bicycle model: mass [kg], yaw inertia [kg m^2], a/b [m], C_f/C_r [N/rad]."""

    mass_kg: float
    yaw_inertia_kgm2: float
    a_m: float
    b_m: float
    c_front_n_per_rad: float
    c_rear_n_per_rad: float

    @classmethod
    def from_vehicle(cls, vehicle: VehicleParams, tire: TireParams) -> SingleTrack:
        front, rear = axle_tires(vehicle, tire)
        fz_f = 0.5 * vehicle.static_axle_load_front_n
        fz_r = 0.5 * vehicle.static_axle_load_rear_n
        return cls(
            mass_kg=vehicle.mass_kg,
            yaw_inertia_kgm2=vehicle.yaw_inertia_kgm2,
            a_m=vehicle.cg_to_front_axle_m,
            b_m=vehicle.cg_to_rear_axle_m,
            c_front_n_per_rad=2.0 * cornering_stiffness(front.coefficients(), fz_f),
            c_rear_n_per_rad=2.0 * cornering_stiffness(rear.coefficients(), fz_r),
        )

    @property
    def wheelbase_m(self) -> float:
        return self.a_m + self.b_m

    @property
    def understeer_gradient_rad_per_mps2(self) -> float:
        """K in δ = L/R + K a_y (rad per m/s^2); > 0 is understeer."""
        return (self.mass_kg / self.wheelbase_m) * (
            self.b_m / self.c_front_n_per_rad - self.a_m / self.c_rear_n_per_rad
        )

    def steady_state(self, speed_mps: float) -> tuple[float, float]:
        """Steady-state gains (β/δ, r/δ) at speed_mps for a mean road-wheel angle δ.

        Solves the linear equations with β̇ = ṙ = 0:
        m u r = C_f (δ − β − a r/u) + C_r (−β + b r/u),
        0 = a C_f (δ − β − a r/u) − b C_r (−β + b r/u).
        """
        u = speed_mps
        cf, cr, a, b = self.c_front_n_per_rad, self.c_rear_n_per_rad, self.a_m, self.b_m
        lhs = np.array(
            [
                [cf + cr, self.mass_kg * u + (a * cf - b * cr) / u],
                [a * cf - b * cr, (a * a * cf + b * b * cr) / u],
            ]
        )
        rhs = np.array([cf, a * cf])
        beta_gain, yaw_gain = np.linalg.solve(lhs, rhs)
        return float(beta_gain), float(yaw_gain)

    def lateral_acceleration_gain(self, speed_mps: float) -> float:
        """Steady-state a_y/δ [m/s^2 per rad] = u · r/δ."""
        return speed_mps * self.steady_state(speed_mps)[1]


def estimator_parameters(vehicle: VehicleParams, tire: TireParams) -> dict[str, float | str]:
    """The estimator's ``single_track`` back-end parameters for this vehicle.

    The estimator does not import the simulator (DESIGN.md), so its observer reads
    these numbers from a YAML file; this function writes the shipped ones and lets a
    user make one for their own vehicle file (``python -m sideslip_sim.single_track``).
    """
    model = SingleTrack.from_vehicle(vehicle, tire)
    return {
        "name": vehicle.name,
        "mass_kg": model.mass_kg,
        "yaw_inertia_kgm2": model.yaw_inertia_kgm2,
        "cg_to_front_axle_m": model.a_m,
        "cg_to_rear_axle_m": model.b_m,
        "cornering_stiffness_front_n_per_rad": round(model.c_front_n_per_rad, 1),
        "cornering_stiffness_rear_n_per_rad": round(model.c_rear_n_per_rad, 1),
        "stl_per_road_wheel_angle_m_per_rad": vehicle.stl_per_road_wheel_angle_m_per_rad,
    }


def main(argv: list[str] | None = None) -> int:
    """Print the single-track observer parameters of a vehicle as YAML."""
    import argparse

    import yaml

    from sideslip_sim.tire import load_tire
    from sideslip_sim.vehicle import VehicleFileError, load_vehicle

    parser = argparse.ArgumentParser(
        prog="python -m sideslip_sim.single_track",
        description="Print the estimator's single_track parameters (YAML) for a vehicle: "
        "linear bicycle model with axle cornering stiffness at the static loads.",
    )
    parser.add_argument("vehicle", help="shipped vehicle name or path to a vehicle YAML")
    args = parser.parse_args(argv)
    try:
        vehicle = load_vehicle(args.vehicle)
        params = estimator_parameters(vehicle, load_tire(str(vehicle.tire_path())))
    except (VehicleFileError, OSError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"# single-track parameters of {vehicle.name} (python -m sideslip_sim.single_track)")
    print(yaml.safe_dump(params, sort_keys=False), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
