"""Steady-state lateral acceleration for Table 3's STL amplitudes (README "Steering scale").

For each amplitude and speed: the linear single-track prediction and the full 14-DOF
model's value after a 6-s step steer held at cruise torque (python bench/steering_scale.py).
"""

from __future__ import annotations

import sys

import numpy as np

from sideslip_sim import dynamics as dyn
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.simulate import prepare, simulate
from sideslip_sim.vehicle import GRAVITY_MPS2, load_vehicle


def main(vehicle_name: str = "paper_sedan") -> None:
    vehicle = load_vehicle(vehicle_name)
    prepared = prepare(vehicle)
    p = prepared.params
    ratio = vehicle.stl_per_road_wheel_angle_m_per_rad
    print(f"vehicle {vehicle.name}: {ratio} m STL per rad road-wheel angle")
    print("| STL [m] | speed [km/h] | δ [deg] | a_y linear [m/s²] | a_y 14-DOF [m/s²] |", end="")
    print(" β 14-DOF [deg] |")
    print("|---|---|---|---|---|---|")
    for stl in (0.06, 0.08, 0.10, 0.11):
        for kmh in (60, 70, 80, 90):
            u = kmh / 3.6
            resist = p[dyn.P_HALF_RHO_CDA] * u * u + p[dyn.P_FRR] * vehicle.mass_kg * GRAVITY_MPS2
            torque = resist * vehicle.tire_rolling_radius_m
            delta = stl / ratio
            linear = prepared.single_track.lateral_acceleration_gain(u) * delta
            r = simulate(
                vehicle, Maneuver("s", "step_steer", 6.0, kmh, torque, stl_amplitude_m=stl)
            )
            tail = slice(-200, None)
            ay = float(np.mean(r.ay_mps2[tail]))
            beta = float(np.degrees(np.mean(r.beta_rad[tail])))
            cells = (
                f"{stl:.2f}",
                str(kmh),
                f"{np.degrees(delta):.2f}",
                f"{linear:.2f}",
                f"{ay:.2f}",
                f"{beta:.2f}",
            )
            print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main(*sys.argv[1:])
