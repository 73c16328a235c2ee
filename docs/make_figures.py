"""Figures for the README and docs: `.venv/bin/python docs/make_figures.py`.

paper_test_scenarios.png: the four Table 4 scenarios on paper_sedan (exact signals):
STL, lateral acceleration, yaw rate and sideslip angle over time, and the path.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sideslip_sim.presets import TABLE4, paper_test
from sideslip_sim.simulate import simulate
from sideslip_sim.vehicle import load_vehicle

OUT = Path(__file__).resolve().parent / "figures"


def paper_test_scenarios(vehicle_name: str = "paper_sedan") -> Path:
    vehicle = load_vehicle(vehicle_name)
    fig, axes = plt.subplots(5, 4, figsize=(15, 13), sharex="col")
    for col, m in enumerate(paper_test()):
        r = simulate(vehicle, m)
        desc = TABLE4[m.name][0]
        rows = [
            (r.stl_m * 1000.0, "STL [mm]"),
            (r.ay_mps2, "a_y [m/s²]"),
            (np.degrees(r.yaw_rate_radps), "yaw rate [deg/s]"),
            (np.degrees(r.beta_rad), "β [deg]"),
        ]
        for row, (values, label) in enumerate(rows):
            ax = axes[row, col]
            ax.plot(r.t_s, values, lw=1.0)
            ax.grid(alpha=0.3)
            if col == 0:
                ax.set_ylabel(label)
        axes[0, col].set_title(f"{m.name}: {desc}\n{m.speed_kmh:.0f} km/h, {m.torque_nm:.0f} N m")
        axes[3, col].set_xlabel("t [s]")
        axes[3, col].tick_params(labelbottom=True)
        path_ax = axes[4, col]
        path_ax.remove()
        path_ax = fig.add_subplot(5, 4, 17 + col)
        path_ax.plot(r.x_m, r.y_m, lw=1.0)
        path_ax.set_aspect("equal", adjustable="datalim")
        path_ax.set_xlabel("X [m]")
        if col == 0:
            path_ax.set_ylabel("Y [m]")
        path_ax.grid(alpha=0.3)
    fig.suptitle(f"Table 4 test scenarios on {vehicle.name} (14-DOF model, exact signals)")
    fig.tight_layout()
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / "paper_test_scenarios.png"
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


if __name__ == "__main__":
    print(paper_test_scenarios())
