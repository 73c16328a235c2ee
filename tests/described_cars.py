"""Shipped cars as their owners would describe them (``sideslip-fit --vehicle``)."""

from __future__ import annotations

from pathlib import Path


def describe_compact_rwd(path: Path) -> Path:
    """Write ``compact_rwd`` as its owner would describe it (``sideslip-fit --vehicle``)
    to ``path``; returns it."""
    import yaml

    from sideslip_sim.vehicle import load_vehicle

    car = load_vehicle("compact_rwd")
    path.write_text(
        yaml.safe_dump(
            {
                "name": "my_car",
                "mass_kg": car.mass_kg,
                "wheelbase_m": car.wheelbase_m,
                "cg_to_front_axle_m": car.cg_to_front_axle_m,
                "cg_height_m": car.cg_height_m,
                "track_m": car.track_front_m,
                "stl_per_road_wheel_angle_m_per_rad": car.stl_per_road_wheel_angle_m_per_rad,
                "tire_rolling_radius_m": car.tire_rolling_radius_m,
                "drive_layout": "rwd",
            }
        )
    )
    return path
