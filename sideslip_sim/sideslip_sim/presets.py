"""Named sets of manoeuvres: the paper's training grid and test scenarios, and seeded
randomised draws for larger data sets.

paper-train: every family of Table 3 and the full grid of its listed values
(amplitude × speed × torque, and time × speed for cornering). Table 3's STL values are
"±": the first steering direction alternates through the grid, so left and right are
equally represented without doubling the set. Random steer crosses the 7 speeds with
the 4 torques (28 runs) and cycles the 3 durations; its amplitude is automatic.

paper-test: the four scenarios of Table 4, with seeds disjoint from training.

randomized: `count` runs drawn from a seeded generator: family, initial speed
20-120 km/h, road μ 0.3-1.0, drive torque 0-600·μ N m, steering severity 0.2-0.9 of the
μ-limited lateral acceleration, payload 0-300 kg, duration 6-15 s.
"""

from __future__ import annotations

import itertools

import numpy as np

from sideslip_sim.maneuvers import Maneuver

PRESETS = ("paper-train", "paper-test", "randomized")

# Table 3 of the reference paper (shared/reference/paper-tables.yaml).
TABLE3 = {
    "straight": {"time_s": [5], "speed_kmh": [50, 90], "torque_nm": [50, 500]},
    "double_lane_change": {
        "stl_m": [0.06, 0.08, 0.10], "time_s": [5], "speed_kmh": [60, 70, 90],
        "torque_nm": [50, 300, 500],
    },
    "sine_steer": {
        "stl_m": [0.06, 0.08, 0.10], "time_s": [8], "speed_kmh": [70, 80, 90],
        "torque_nm": [400, 500, 600],
    },
    "sweep_steer": {
        "stl_m": [0.10, 0.11], "time_s": [9], "speed_kmh": [60, 80, 90],
        "torque_nm": [400, 500, 600],
    },
    "cornering": {"time_s": [3, 4, 5, 6], "speed_kmh": [10, 30, 50, 90], "torque_nm": [500]},
    "random_steer": {
        "time_s": [15, 17, 18], "speed_kmh": [40, 50, 60, 70, 80, 90, 100],
        "torque_nm": [300, 500, 550, 600],
    },
}  # fmt: skip

# Table 4: description, initial speed, torque, duration.
TABLE4 = {
    "scen1": ("DLC + sine steer", 80.0, 500.0, 9.5),
    "scen2": ("DLC + cornering", 90.0, 500.0, 10.5),
    "scen3": ("continuous sine steer", 75.0, 500.0, 9.5),
    "scen4": ("random steer", 75.0, 500.0, 8.0),
}
_TEST_SEED_OFFSET = 1000  # random-steer seeds of the test scenarios never occur in training


class PresetError(ValueError):
    """Unknown preset name or bad preset option."""


def paper_train() -> list[Maneuver]:
    runs: list[Maneuver] = []
    t3 = TABLE3
    for v, tq in itertools.product(t3["straight"]["speed_kmh"], t3["straight"]["torque_nm"]):
        runs.append(Maneuver(f"straight_v{v}_t{tq}", "straight", 5.0, v, tq))
    for family, prefix in (
        ("double_lane_change", "dlc"),
        ("sine_steer", "sine"),
        ("sweep_steer", "sweep"),
    ):
        spec = t3[family]
        grid = itertools.product(spec["stl_m"], spec["speed_kmh"], spec["torque_nm"])
        for i, (stl, v, tq) in enumerate(grid):
            sign = 1.0 if i % 2 == 0 else -1.0
            side = "l" if sign > 0 else "r"
            runs.append(
                Maneuver(
                    f"{prefix}_a{int(stl * 1000)}{side}_v{v}_t{tq}",
                    family,
                    float(spec["time_s"][0]),
                    v,
                    tq,
                    stl_amplitude_m=sign * stl,
                )
            )
    grid = itertools.product(t3["cornering"]["time_s"], t3["cornering"]["speed_kmh"])
    for i, (dur, v) in enumerate(grid):
        sign = 1.0 if i % 2 == 0 else -1.0
        side = "l" if sign > 0 else "r"
        runs.append(
            Maneuver(
                f"corner_{side}_d{dur}_v{v}_t500",
                "cornering",
                float(dur),
                v,
                500.0,
                stl_amplitude_m=sign,
            )
        )
    spec = t3["random_steer"]
    grid = itertools.product(spec["speed_kmh"], spec["torque_nm"])
    for i, (v, tq) in enumerate(grid):
        dur = spec["time_s"][i % len(spec["time_s"])]
        runs.append(
            Maneuver(f"random_s{i}_d{dur}_v{v}_t{tq}", "random_steer", float(dur), v, tq, seed=i)
        )
    return runs


def paper_test() -> list[Maneuver]:
    return [
        Maneuver(name, "scenario", dur, v, tq, scenario=name, seed=_TEST_SEED_OFFSET + i)
        for i, (name, (_desc, v, tq, dur)) in enumerate(TABLE4.items())
    ]


def randomized(count: int, seed: int) -> list[Maneuver]:
    if count < 1:
        raise PresetError(f"randomized: count must be >= 1, got {count}")
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x5EED])
    families = (
        "double_lane_change",
        "sine_steer",
        "sweep_steer",
        "cornering",
        "random_steer",
        "straight",
    )
    weights = np.array([0.18, 0.2, 0.17, 0.15, 0.25, 0.05])
    runs = []
    for i in range(count):
        family = str(rng.choice(families, p=weights / weights.sum()))
        sign = 1.0 if rng.random() < 0.5 else -1.0
        mu = float(np.round(rng.uniform(0.3, 1.0), 3))
        runs.append(
            Maneuver(
                name=f"rand{seed}_{i:04d}_{family}",
                family=family,
                duration_s=float(np.round(rng.uniform(6.0, 15.0), 2)),
                speed_kmh=float(np.round(rng.uniform(20.0, 120.0), 1)),
                # Scaled by μ so that a low-friction draw does not just spin up the
                # driven axle (no traction control is modelled).
                torque_nm=float(np.round(rng.uniform(0.0, 600.0) * mu, 0)),
                # Cornering reads only the sign; the others take the automatic amplitude.
                stl_amplitude_m=sign if family == "cornering" else 0.0,
                mu=mu,
                seed=int(rng.integers(0, 2**31 - 1)),
                payload_kg=float(np.round(rng.uniform(0.0, 300.0), 1)),
                ay_fraction=float(np.round(rng.uniform(0.2, 0.9), 3)),
            )
        )
    return runs


def preset(name: str, *, seed: int = 0, count: int = 100) -> list[Maneuver]:
    """The manoeuvres of a named preset."""
    if name == "paper-train":
        return paper_train()
    if name == "paper-test":
        return paper_test()
    if name == "randomized":
        return randomized(count, seed)
    raise PresetError(f"unknown preset {name!r}; known: {', '.join(PRESETS)}")
