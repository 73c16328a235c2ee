"""The held-out runs of ``sideslip-benchmark``: generating, loading and picking them.

The bags: the six cars of :mod:`sideslip_sim.held_out`, each at road μ = 1.0, 0.7 and
0.4, through the Table 4 scenarios, a step steer and a sine sweep, with the paper's
sensor noise (``sideslip-generate --preset held-out --noise paper``: 108 runs, or
``sideslip-benchmark --generate``). A bag of any other car is refused: no training set,
PSO or filter tuning ever contains these cars, and nothing else is scored.

:class:`BenchmarkError`, the input the benchmark refuses, lives here, at the bottom of the
benchmark's modules (data → :mod:`.benchmark_estimators` → :mod:`.benchmark_scores` →
:mod:`.benchmark_report`, :mod:`.benchmark_figures` → the CLI :mod:`.benchmark`).
"""

from __future__ import annotations

import dataclasses
import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from .dataset import DatasetError, Run, find_bags, load_runs

PROG: Final = "sideslip-benchmark"


class BenchmarkError(ValueError):
    """Input the benchmark refuses (message names the folder, bag, file or option)."""


class GenerationError(RuntimeError):
    """``--generate`` failed to simulate a run (the message names it)."""


@dataclass(frozen=True, eq=False)
class HeldOutRun:
    """One held-out bag: its samples and what the bag says about the car and the run.

    Attributes:
        run: the samples (units of :class:`~sideslip_msgs_py.sample.SampleArrays`).
        vehicle: the car's full parameters as the bag records them (YAML-ready).
        vehicle_name: the car's name.
        mu: road friction of the run [-].
        kind: ``scen1``..``scen4``, ``step_steer`` or ``sweep_steer``.
        spin_onset_s: time of the first spinning sample [s], or None.
        noise: the bag's sensor-noise profile (``paper`` for the benchmark).
    """

    run: Run
    vehicle: dict[str, Any]
    vehicle_name: str
    mu: float
    kind: str
    spin_onset_s: float | None
    noise: str

    @property
    def name(self) -> str:
        return self.run.name

    @property
    def cell(self) -> tuple[str, float]:
        return (self.vehicle_name, self.mu)


def held_out_runs() -> list[Any]:
    """The preset's runs (``VehicleRun`` of :mod:`sideslip_sim.presets`), in order."""
    from sideslip_sim.presets import vehicle_preset

    return vehicle_preset("held-out")


def _run_order() -> tuple[dict[str, int], dict[str, int]]:
    from sideslip_sim.held_out import HELD_OUT_NAMES
    from sideslip_sim.presets import HELD_OUT_RUNS

    return (
        {n: i for i, n in enumerate(HELD_OUT_NAMES)},
        {k: i for i, k in enumerate(HELD_OUT_RUNS)},
    )


def expected_run_count() -> int:
    """Runs of the full benchmark (6 cars × 3 μ × 6 runs)."""
    from sideslip_sim.held_out import HELD_OUT_MU, HELD_OUT_NAMES
    from sideslip_sim.presets import HELD_OUT_RUNS

    return len(HELD_OUT_NAMES) * len(HELD_OUT_MU) * len(HELD_OUT_RUNS)


def generate_held_out(data: Path, *, jobs: int, progress: bool) -> None:
    """(Re)generate the held-out bags into ``data`` (seed 0, paper noise), as
    ``sideslip-generate --preset held-out --noise paper --force`` does. A non-empty
    ``data`` that is not a held-out folder (its index.json) is refused: its bags would
    be deleted."""
    from sideslip_sim.generate import INDEX_FILE, generate, prepare_output

    if data.is_dir() and any(data.iterdir()):
        index = data / INDEX_FILE
        try:
            preset = json.loads(index.read_text()).get("preset")
        except (OSError, ValueError, AttributeError):
            preset = None
        if preset != "held-out":
            raise BenchmarkError(
                f"--generate: --data {data} is not empty and is not a held-out folder (no "
                f"{INDEX_FILE} of preset held-out); give a new or empty folder"
            )
    from sideslip_sim.maneuvers import ManeuverError
    from sideslip_sim.simulate import SimulationError

    prepare_output(data, force=True)
    try:
        generate(
            held_out_runs(),
            data,
            noise="paper",
            seed=0,
            preset_name="held-out",
            jobs=jobs,
            progress=progress,
        )
    except (SimulationError, ManeuverError) as err:
        raise GenerationError(str(err)) from err


def load_held_out(data: Path, *, progress: bool = True) -> list[HeldOutRun]:
    """The held-out runs under ``data``, in preset order (car, μ descending, run).

    Raises:
        BenchmarkError: no bags, a bag that load_runs could not take verbatim (unreadable,
            no ground truth, gaps, NaN), a bag without run metadata, a car that is not
            held out, or two bags of the same run.
    """
    from sideslip_sim.fleet import vehicle_digest
    from sideslip_sim.held_out import held_out_digests
    from sideslip_sim.vehicle import VehicleFileError, vehicle_from_dict

    if not data.exists():
        raise BenchmarkError(
            f"--data {data}: no such folder; pass --generate to generate the held-out bags"
        )
    try:
        bags = find_bags([data])
    except DatasetError as err:
        raise BenchmarkError(f"{err}; pass --generate to generate the held-out bags") from None
    from tqdm import tqdm

    bar = tqdm(total=len(bags), unit="bag", desc="load", disable=not progress, file=sys.stderr)

    try:
        runs, report = load_runs([data], on_bag=lambda _: bar.update())
    except DatasetError as err:
        raise BenchmarkError(str(err)) from None
    finally:
        bar.close()
    damaged = list(report.refused) + [f"{n}: truncated" for n in report.truncated]
    if report.gaps or report.nonfinite_samples:
        damaged += [line for line in report.lines if "gap" in line or "NaN" in line]
    if damaged:
        raise BenchmarkError(
            f"--data {data}: bags the benchmark cannot score as they are: " + "; ".join(damaged)
        )

    digests = held_out_digests()
    out: list[HeldOutRun] = []
    seen: dict[tuple[str, float, str], str] = {}
    for run in runs:
        meta = run.run_metadata
        try:
            vehicle_dict = meta["vehicle"]
            maneuver = meta["maneuver"]
            vehicle = vehicle_from_dict(vehicle_dict, where=f"{run.path} (vehicle metadata)")
            mu = float(maneuver["mu"])
            kind = str(maneuver.get("scenario") or maneuver["family"])
        except (KeyError, TypeError, ValueError, VehicleFileError) as err:
            raise BenchmarkError(
                f"{run.path}: no car and manoeuvre in its run metadata ({err}); the benchmark "
                "reads bags written by sideslip-generate --preset held-out"
            ) from None
        if vehicle_digest(vehicle) not in digests or meta.get("vehicle_digest") not in digests:
            raise BenchmarkError(
                f"{run.path}: car {vehicle.name!r} is not a held-out car (digest "
                f"{vehicle_digest(vehicle)[:12]}); the benchmark scores only the held-out fleet"
            )
        key = (vehicle.name, mu, kind)
        if key in seen:
            raise BenchmarkError(
                f"{run.path}: a second bag of {vehicle.name} μ={mu:g} {kind} (first: {seen[key]})"
            )
        seen[key] = str(run.path)
        onset = meta.get("spin_onset_s")
        out.append(
            HeldOutRun(
                run=run,
                vehicle=dict(vehicle_dict),
                vehicle_name=vehicle.name,
                mu=mu,
                kind=kind,
                spin_onset_s=None if onset is None else float(onset),
                noise=str(meta.get("noise_profile", "?")),
            )
        )
    car_order, kind_order = _run_order()
    out.sort(
        key=lambda r: (
            car_order.get(r.vehicle_name, len(car_order)),
            r.vehicle_name,
            -r.mu,
            kind_order.get(r.kind, len(kind_order)),
            r.kind,
        )
    )
    return out


def mirrored_runs(runs: Sequence[HeldOutRun]) -> list[HeldOutRun]:
    """Each run driven the other way round (:mod:`sideslip_msgs_py.mirror`; the simulator
    and the filters are symmetric, so it is a drive the car could have made): the same
    car, μ and kind, named ``<name>~mirror``, in the same cell."""
    from sideslip_msgs_py.mirror import mirrored

    from .training_data import MIRROR_SUFFIX

    return [
        dataclasses.replace(
            r,
            run=dataclasses.replace(
                r.run, name=r.run.name + MIRROR_SUFFIX, samples=mirrored(r.run.samples)
            ),
        )
        for r in runs
    ]


def limit_runs(runs: Sequence[HeldOutRun], per_cell: int) -> list[HeldOutRun]:
    """The first ``per_cell`` runs (preset order) of every car × μ cell."""
    kept: list[HeldOutRun] = []
    count: dict[tuple[str, float], int] = {}
    for r in runs:
        count[r.cell] = count.get(r.cell, 0) + 1
        if count[r.cell] <= per_cell:
            kept.append(r)
    return kept
