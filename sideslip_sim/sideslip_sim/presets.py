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

Multi-vehicle presets (`vehicle_preset`), each run with its own car:

fleet: `count` runs on cars of the fleet sampler (`sideslip_sim.fleet`), four per car.

held-out: the held-out benchmark (`sideslip_sim.held_out`): never for training.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from sideslip_sim.fleet import sample_fleet
from sideslip_sim.held_out import HELD_OUT_MU, held_out_digests, held_out_vehicles
from sideslip_sim.maneuvers import MAX_BANK_PCT, Maneuver, auto_stl_amplitude
from sideslip_sim.single_track import SingleTrack
from sideslip_sim.tire import load_tire
from sideslip_sim.vehicle import VehicleParams

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


# ---- presets whose runs each name their own car -------------------------------------

VEHICLE_PRESETS = ("fleet", "held-out")
# Training presets of the one-car kind: they refuse a held-out car as --vehicle.
TRAINING_PRESETS = ("paper-train", "randomized", "fleet")
FLEET_RUNS_PER_CAR = 4
_FLEET_FAMILIES = (
    "double_lane_change",
    "sine_steer",
    "sweep_steer",
    "cornering",
    "random_steer",
    "step_steer",
    "straight",
)
_FLEET_WEIGHTS = np.array([0.16, 0.16, 0.16, 0.12, 0.22, 0.14, 0.04])
# Held-out benchmark: Table 4 scenarios plus a step steer and a sine sweep per car and μ.
HELD_OUT_RUNS = (*TABLE4, "step_steer", "sweep_steer")
HELD_OUT_SPEED_KMH = {"step_steer": 80.0, "sweep_steer": 80.0}
HELD_OUT_AY_FRACTION = 0.85  # of μ·g in steady state: near the limit, not over it
# Second seed word of the crossfall draws, so they never share a stream with a preset's.
_BANK_STREAM = 0xBA4C


@dataclass(frozen=True)
class VehicleRun:
    """One run of a multi-vehicle preset: the car and what it drives."""

    vehicle: VehicleParams
    maneuver: Maneuver


def on_bank(run: VehicleRun, bank_pct: float) -> VehicleRun:
    """``run`` on a road falling to the right of its start heading by ``bank_pct`` [%] (a
    run turned the other way, ``side`` −1, mirrors its road too, so it is given
    −bank_pct: its road still falls to the right)."""
    m = run.maneuver
    return dataclasses.replace(run, maneuver=dataclasses.replace(m, bank_pct=bank_pct * m.side))


def on_random_banks(runs: Sequence[VehicleRun], spread_pct: float, seed: int) -> list[VehicleRun]:
    """``runs`` each on its own crossfall, drawn uniformly in [−spread_pct, spread_pct] [%]
    (falling to the right of the start heading when > 0, as ``on_bank``).

    Its own generator (seeded by ``seed``): the cars and manoeuvres are those of the same
    preset without crossfall, so a trained model can be compared run for run. Uniform
    rather than clustered at the 2.5 % drain slope because drains fall either way of a
    run's heading and curves are superelevated further; ``spread_pct`` ≤ MAX_BANK_PCT."""
    if not 0.0 < spread_pct <= MAX_BANK_PCT:  # (NaN fails too)
        raise PresetError(f"bank spread must be in (0, {MAX_BANK_PCT:g}] %, got {spread_pct}")
    rng = np.random.default_rng([seed, _BANK_STREAM])
    banks = rng.uniform(-spread_pct, spread_pct, size=len(runs))
    return [
        dataclasses.replace(r, maneuver=dataclasses.replace(r.maneuver, bank_pct=float(b)))
        for r, b in zip(runs, banks, strict=True)
    ]


def fleet(count: int, seed: int, *, both_sides: bool = False) -> list[VehicleRun]:
    """`count` runs on ceil(count / 4) cars of the fleet sampler (seeded), four runs per
    car: family, initial speed 30-130 km/h, road μ 0.3-1.0, steering severity 0.3-1.0
    of the μ-limited lateral acceleration (up to the friction limit), drive torque
    scaled by μ and mass, duration 6-12 s. Held-out cars are never drawn.

    Cornering draws its side; the other scripted families open to the left unless
    ``both_sides`` (then each run drives its drawn side: a model trained on one side
    learns it, docs/evaluation/direction). Off by default so that a seed gives the data
    the shipped models were trained on."""
    if count < 1:
        raise PresetError(f"fleet: count must be >= 1, got {count}")
    cars = sample_fleet(
        math.ceil(count / FLEET_RUNS_PER_CAR), seed, exclude_digests=held_out_digests()
    ).vehicles
    return fleet_runs(cars, count, seed, both_sides=both_sides)


def fleet_runs(
    cars: Sequence[VehicleParams], count: int, seed: int, *, both_sides: bool = False
) -> list[VehicleRun]:
    """The fleet preset's runs on given cars (four per car, in order; see :func:`fleet`).
    ``both_sides`` changes only which way a run turns, not what else is drawn."""
    if count > FLEET_RUNS_PER_CAR * len(cars):
        raise PresetError(f"fleet: {count} runs need {math.ceil(count / 4)} cars")
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0xF1EE7, 1])
    runs = []
    for i in range(count):
        car = cars[i // FLEET_RUNS_PER_CAR]
        family = str(rng.choice(_FLEET_FAMILIES, p=_FLEET_WEIGHTS / _FLEET_WEIGHTS.sum()))
        sign = 1.0 if rng.random() < 0.5 else -1.0
        mu = float(np.round(rng.uniform(0.3, 1.0), 3))
        torque = rng.uniform(0.0, 400.0) * mu * car.mass_kg / 1500.0
        runs.append(
            VehicleRun(
                car,
                Maneuver(
                    name=f"{car.name}_{i % FLEET_RUNS_PER_CAR}_{family}",
                    family=family,
                    duration_s=float(np.round(rng.uniform(6.0, 12.0), 2)),
                    speed_kmh=float(np.round(rng.uniform(30.0, 130.0), 1)),
                    torque_nm=float(np.round(torque, 0)),
                    stl_amplitude_m=sign if family == "cornering" else 0.0,
                    mu=mu,
                    seed=int(rng.integers(0, 2**31 - 1)),
                    ay_fraction=float(np.round(rng.uniform(0.3, 1.0), 3)),
                    # Cornering's amplitude already carries its side.
                    side=int(sign) if both_sides and family != "cornering" else 1,
                ),
            )
        )
    return runs


def held_out() -> list[VehicleRun]:
    """The held-out benchmark: every held-out car at μ = 1.0, 0.7, 0.4 through the
    Table 4 scenarios (their speed and duration, their torque scaled by μ as in the
    randomized preset), a step steer and a sine sweep
    (80 km/h, 10 s). Steering amplitudes are each car's own: the STL whose steady-state
    lateral acceleration is 0.85·μ·g at the run's speed (the paper's fixed STL values
    would be a different severity on every car)."""
    return benchmark_runs(held_out_vehicles())


def benchmark_runs(cars: Mapping[str, VehicleParams]) -> list[VehicleRun]:
    """The held-out benchmark's runs (see :func:`held_out`) on other ``cars`` (tag →
    car): e.g. validation cars, to choose on the kind of driving the benchmark scores."""
    runs = []
    for name, car in cars.items():
        for mu in HELD_OUT_MU:
            for j, run in enumerate(HELD_OUT_RUNS):
                tag = f"{name}_mu{round(mu * 10):02d}_{run}"
                seed = _TEST_SEED_OFFSET + 100 + j
                if run in TABLE4:
                    _desc, speed, torque, duration = TABLE4[run]
                    maneuver = Maneuver(
                        tag, "scenario", duration, speed, torque * mu, scenario=run, mu=mu,
                        seed=seed, ay_fraction=HELD_OUT_AY_FRACTION,
                        stl_amplitude_m=_held_out_amplitude(car, speed, mu),
                    )  # fmt: skip
                else:
                    speed = HELD_OUT_SPEED_KMH[run]
                    maneuver = Maneuver(
                        tag, run, 10.0, speed, 300.0 * mu, mu=mu, seed=seed,
                        ay_fraction=HELD_OUT_AY_FRACTION,
                    )  # fmt: skip
                runs.append(VehicleRun(car, maneuver))
    return runs


def _held_out_amplitude(car: VehicleParams, speed_kmh: float, mu: float) -> float:
    """Scenario STL amplitude of a held-out car (scen1 and scen3 read it; the path-
    following scenarios steer by the driver and ignore it)."""
    tire = load_tire(str(car.tire_path()))
    model = SingleTrack.from_vehicle(car, tire)
    return auto_stl_amplitude(car, model, speed_kmh / 3.6, mu, HELD_OUT_AY_FRACTION)


def vehicle_preset(
    name: str, *, seed: int = 0, count: int = 100, both_sides: bool = False
) -> list[VehicleRun]:
    """The runs (each with its car) of a multi-vehicle preset (``both_sides``: fleet)."""
    if name == "fleet":
        return fleet(count, seed, both_sides=both_sides)
    if name == "held-out":
        return held_out()
    raise PresetError(f"unknown vehicle preset {name!r}; known: {', '.join(VEHICLE_PRESETS)}")
