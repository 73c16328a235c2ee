"""Labelled bag generation: manoeuvres → simulation → sensor noise → rosbag2 MCAP bags.

`generate_run` is the pure-ish unit of work (one manoeuvre → one bag); `generate` runs
a preset over a process pool; the `sideslip-generate` CLI is :mod:`.generate_cli`.
"""

from __future__ import annotations

import concurrent.futures as futures
import dataclasses
import hashlib
import json
import multiprocessing
import platform
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from sideslip_msgs_py.bag import write_bag
from sideslip_msgs_py.data_source import SIMULATOR
from sideslip_msgs_py.sample import SensorNoiseSigma
from sideslip_sim import __version__
from sideslip_sim.fleet import vehicle_digest
from sideslip_sim.imu_mounting import ImuMounting
from sideslip_sim.maneuvers import Maneuver, ManeuverError
from sideslip_sim.plausibility import plausibility
from sideslip_sim.presets import (
    VehicleRun,
)
from sideslip_sim.sensors import add_noise, exact_samples, noise_profile, run_seed
from sideslip_sim.simulate import DT_S, SimResult, simulate
from sideslip_sim.tire import load_tire
from sideslip_sim.vehicle import VehicleParams, vehicle_record

INDEX_FILE = "index.json"
EXIT_BAD_INPUT = 2
EXIT_RUN_FAILED = 1
# A run "spun" when |β| exceeded this above SPIN_MIN_SPEED_MPS: beyond any kinematic
# (low-speed) sideslip, the car has lost control. Such runs are kept (they are real
# physics, e.g. a near-neutral rear-drive car on ice) but flagged in index.json.
SPIN_BETA_DEG = 30.0
SPIN_MIN_SPEED_MPS = 5.0


class OutputDirError(ValueError):
    """The output directory exists with content and --force was not given."""


@dataclass(frozen=True)
class RunSummary:
    """What one generated bag holds, for the index and the printed summary."""

    name: str
    family: str
    vehicle: str
    bag: str
    samples: int
    duration_s: float
    peak_abs_beta_deg: float
    peak_abs_ay_mps2: float
    peak_abs_yaw_rate_degps: float
    speed_start_kmh: float
    speed_end_kmh: float
    speed_min_kmh: float
    mu: float
    spun: bool
    spin_onset_s: float | None
    sim_wall_s: float


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def spin_onset_s(result: SimResult) -> float | None:
    """Time [s] of the first sample where the run spun (see SPIN_BETA_DEG), or None."""
    spinning = (np.abs(np.degrees(result.beta_rad)) > SPIN_BETA_DEG) & (
        result.u_mps > SPIN_MIN_SPEED_MPS
    )
    return float(result.t_s[np.argmax(spinning)]) if spinning.any() else None


def run_metadata(
    vehicle: VehicleParams,
    maneuver: Maneuver,
    noise: str,
    sigma: SensorNoiseSigma,
    seed: int,
    preset_name: str,
    spin_onset: float | None = None,
    imu: ImuMounting | None = None,
) -> dict[str, object]:
    """Everything needed to regenerate the bag bit for bit, stored inside it, with the
    car's parameter digest and plausibility figures and the run's spin onset (or None):
    a run that spun is kept, and training decides what to do with it."""
    tire_path = vehicle.tire_path()
    tire = load_tire(str(tire_path))
    return {
        "generator": f"{SIMULATOR} {__version__}",  # what data_source.is_simulated reads
        "preset": preset_name,
        "maneuver": maneuver.to_dict(),
        "vehicle": vehicle_record(vehicle),
        "vehicle_digest": vehicle_digest(vehicle),
        "vehicle_checks": dataclasses.asdict(plausibility(vehicle, tire)),
        "spin_onset_s": spin_onset,
        "tire_file": tire_path.name,
        "tire_sha256": _file_digest(tire_path),
        "noise_profile": noise,
        "noise_sigma": dataclasses.asdict(sigma),
        "imu": (imu or ImuMounting()).to_dict(),
        "seed": seed,
        "dt_s": DT_S,
        "integrator": "RK4 (classic 4th order), fixed step",
        "python": platform.python_version(),
    }


def generate_run(
    vehicle: VehicleParams,
    maneuver: Maneuver,
    out_dir: Path,
    *,
    noise: str,
    seed: int,
    preset_name: str,
    imu: ImuMounting | None = None,
) -> RunSummary:
    """Simulate one manoeuvre and write its bag to out_dir/<maneuver.name> (``imu``: the
    IMU's mounting, by default the contract's ideal one)."""
    started = time.perf_counter()
    result = simulate(vehicle, maneuver)
    sim_wall = time.perf_counter() - started
    sigma = noise_profile(noise)
    exact = exact_samples(result, imu=imu)
    samples = add_noise(exact, sigma, run_seed(seed, maneuver.name))
    bag = out_dir / maneuver.name
    onset = spin_onset_s(result)
    write_bag(
        bag,
        samples,
        sigma=sigma,
        run_metadata=run_metadata(vehicle, maneuver, noise, sigma, seed, preset_name, onset, imu),
    )
    speed_kmh = result.u_mps * 3.6
    return RunSummary(
        name=maneuver.name,
        family=maneuver.scenario or maneuver.family,
        vehicle=vehicle.name,
        bag=bag.name,
        samples=len(result),
        duration_s=maneuver.duration_s,
        peak_abs_beta_deg=float(np.degrees(np.max(np.abs(result.beta_rad)))),
        peak_abs_ay_mps2=float(np.max(np.abs(result.ay_mps2))),
        peak_abs_yaw_rate_degps=float(np.degrees(np.max(np.abs(result.yaw_rate_radps)))),
        speed_start_kmh=float(speed_kmh[0]),
        speed_end_kmh=float(speed_kmh[-1]),
        speed_min_kmh=float(np.min(speed_kmh)),
        mu=maneuver.mu,
        spun=onset is not None,
        spin_onset_s=onset,
        sim_wall_s=sim_wall,
    )


def prepare_output(out_dir: Path, *, force: bool) -> None:
    """Create out_dir; refuse a non-empty one unless force. With force, only bags (folders
    holding a metadata.yaml) and our index are removed: nothing else of the user's."""
    if out_dir.exists() and not out_dir.is_dir():
        raise OutputDirError(f"--out {out_dir} exists and is not a directory")
    if out_dir.is_dir() and any(out_dir.iterdir()):
        if not force:
            raise OutputDirError(
                f"--out {out_dir} exists and is not empty; pass --force to replace its bags"
            )
        for child in out_dir.iterdir():
            if child.is_dir() and (child / "metadata.yaml").is_file():
                shutil.rmtree(child)
            elif child.name == INDEX_FILE:
                child.unlink()
    out_dir.mkdir(parents=True, exist_ok=True)


def _warm_up(vehicle: VehicleParams) -> None:
    """Compile (or load from cache) the model once before forking workers."""
    simulate(vehicle, Maneuver("warm_up", "straight", 0.01, 10.0, 0.0))


def single_vehicle(vehicle: VehicleParams, maneuvers: Sequence[Maneuver]) -> list[VehicleRun]:
    """The runs of a one-car preset: every manoeuvre on the same vehicle."""
    return [VehicleRun(vehicle, m) for m in maneuvers]


def generate(
    runs: Sequence[VehicleRun],
    out_dir: Path,
    *,
    noise: str = "paper",
    seed: int = 0,
    preset_name: str = "custom",
    jobs: int = 1,
    progress: bool = True,
    on_done: Callable[[RunSummary], None] | None = None,
    imu: ImuMounting | None = None,
) -> list[RunSummary]:
    """Generate one bag per run into out_dir (which must be prepared) and an index."""
    noise_profile(noise)  # validate before any work
    names = [r.maneuver.name for r in runs]
    if len(set(names)) != len(names):
        raise ManeuverError("manoeuvre names must be unique: each names its bag")
    if not runs:
        raise ManeuverError("no runs to generate")
    _warm_up(runs[0].vehicle)
    summaries: list[RunSummary] = []
    kwargs = {"noise": noise, "seed": seed, "preset_name": preset_name, "imu": imu}
    bar = tqdm(total=len(runs), unit="run", desc="generate", disable=not progress, file=sys.stderr)
    if jobs <= 1:
        for r in runs:
            summaries.append(generate_run(r.vehicle, r.maneuver, out_dir, **kwargs))
            bar.update(1)
    else:
        ctx = multiprocessing.get_context("fork")
        with futures.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
            pending = [
                pool.submit(generate_run, r.vehicle, r.maneuver, out_dir, **kwargs) for r in runs
            ]
            for fut in futures.as_completed(pending):
                summaries.append(fut.result())
                bar.update(1)
    bar.close()
    order = {name: i for i, name in enumerate(names)}
    summaries.sort(key=lambda s: order[s.name])
    vehicles = sorted({r.vehicle.name for r in runs})
    index = {
        "preset": preset_name,
        "vehicle": vehicles[0] if len(vehicles) == 1 else vehicles,
        "noise": noise,
        "seed": seed,
        "imu": (imu or ImuMounting()).to_dict(),
        "runs": [dataclasses.asdict(s) for s in summaries],
    }
    (out_dir / INDEX_FILE).write_text(json.dumps(index, indent=1) + "\n", encoding="utf-8")
    if on_done:
        for s in summaries:
            on_done(s)
    return summaries
