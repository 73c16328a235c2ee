"""A car's parameter files for the estimator's physics back-ends, from its simulator
parameters: what the held-out benchmark gives each filter and what the UKF observer
inputs of a model are computed with. One home for both (the benchmark and the observer
import it; neither imports the other).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import yaml


def nominal_parameters(backend: str, vehicle: Mapping[str, Any]) -> dict[str, Any]:
    """The ``params_file`` contents of ``backend`` for a car (its true nominal values)."""
    from sideslip_sim.tire import load_tire
    from sideslip_sim.vehicle import vehicle_from_dict

    car = vehicle_from_dict(dict(vehicle))
    tire = load_tire(str(car.tire_path()))
    if backend == "single_track":
        from sideslip_sim.single_track import estimator_parameters

        return estimator_parameters(car, tire)
    if backend == "ukf":
        from sideslip_sim.axle_tires import axle_tires
        from sideslip_sim.ukf_params import ukf_parameters

        front, rear = axle_tires(car, tire)
        return ukf_parameters(car, front, rear)
    raise ValueError(f"no nominal parameters for back-end {backend!r}")


def params_yaml(backend: str, vehicle: str, values: Mapping[str, Any], by: str) -> str:
    """A back-end's ``params_file``: ``values`` as YAML under a line naming the car."""
    return (
        f"# {backend} parameters of {vehicle}: its true nominal values, written by "
        f"{by}\n" + yaml.safe_dump(dict(values), sort_keys=False)
    )


def steering_limit_m(vehicle: Mapping[str, Any]) -> float:
    """The estimator's ``limits.stl_m`` for a car [m]: 1.5 × its STL at full lock, and
    never below the node's default. The default (0.5 m) is below the full lock of the
    held-out cars (STL per road-wheel angle 1.3-2.0 m/rad), whose path-following runs
    reach it: the node would reject those samples as sensor faults."""
    from sideslip_estimator.inputs import InputLimits

    full_lock_m = float(vehicle["stl_per_road_wheel_angle_m_per_rad"]) * float(
        vehicle["max_road_wheel_angle_rad"]
    )
    return max(InputLimits().stl_m, 1.5 * full_lock_m)
