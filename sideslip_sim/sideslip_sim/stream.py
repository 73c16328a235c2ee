"""What the sim node publishes, without ROS: manoeuvres → noisy samples → CDR bytes.

Each run is simulated whole through the same batch path as ``sideslip-generate``
(a 30-s run takes about 30 ms), with the same per-run noise seed, so the node
publishes exactly the samples a generated bag holds for the same run, noise and seed
(only the stamps differ: the node's start at wall time). Runs follow each other on
one continuous time line with a pause of :data:`RUN_PAUSE_S` between them, so that an
estimator sees a gap (and restarts its window) instead of a teleported car.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np

from sideslip_msgs_py.cdr import ByteRows, SampleEncoder
from sideslip_msgs_py.sample import (
    SENSOR_CHANNELS,
    TRUTH_CHANNELS,
    SampleArrays,
    SensorNoiseSigma,
)
from sideslip_sim.imu_mounting import ImuMounting
from sideslip_sim.maneuvers import FAMILIES, SCENARIOS, Maneuver, ManeuverError
from sideslip_sim.presets import PRESETS, paper_test, preset
from sideslip_sim.sensors import add_noise, exact_samples, run_seed
from sideslip_sim.simulate import DT_S, simulate
from sideslip_sim.vehicle import VehicleParams

DT_NS: Final = round(DT_S * 1e9)
RUN_PAUSE_S: Final = 0.5
"""Silence between consecutive runs (longer than the estimator's default max_gap_s)."""


@dataclass(frozen=True)
class ManeuverSpec:
    """Settings for a single manoeuvre family run (the node's ``maneuver.*`` parameters)."""

    duration_s: float = 20.0
    speed_kmh: float = 80.0
    torque_nm: float = 0.0
    stl_amplitude_m: float = 0.0
    mu: float = 1.0
    bank_pct: float = 0.0


def select_runs(
    scenario: str, *, seed: int = 0, count: int = 10, spec: ManeuverSpec | None = None
) -> list[Maneuver]:
    """The runs a ``scenario`` parameter names.

    * ``scen1`` .. ``scen4``: one Table 4 test scenario (as in the ``paper-test`` preset);
    * a preset (``paper-test``, ``paper-train``, ``randomized`` with ``count`` runs);
    * a manoeuvre family (``sine_steer``, ``double_lane_change``, ...) built from ``spec``.

    Raises :class:`ValueError` naming the known choices for anything else.
    """
    if scenario in SCENARIOS:
        return [m for m in paper_test() if m.scenario == scenario]
    if scenario in PRESETS:
        return preset(scenario, seed=seed, count=count)
    if scenario in FAMILIES and scenario != "scenario":
        s = spec or ManeuverSpec()
        return [
            Maneuver(
                name=f"{scenario}_v{s.speed_kmh:g}",
                family=scenario,
                duration_s=s.duration_s,
                speed_kmh=s.speed_kmh,
                torque_nm=s.torque_nm,
                stl_amplitude_m=s.stl_amplitude_m,
                mu=s.mu,
                seed=seed,
                bank_pct=s.bank_pct,
            )
        ]
    families = [f for f in FAMILIES if f != "scenario"]
    msg = (
        f"unknown scenario {scenario!r}; known: {', '.join(SCENARIOS)}, presets "
        f"{', '.join(PRESETS)}, families {', '.join(families)}"
    )
    raise ManeuverError(msg)


@dataclass(frozen=True)
class RunChunk:
    """One run, ready to publish: samples (stamped on the stream's time line) and bytes."""

    maneuver: Maneuver
    samples: SampleArrays
    messages: dict[str, ByteRows]
    """Topic → (n, size) CDR rows, ground-truth topics included when requested."""


class SampleStream:
    """Runs one after another (forever when ``loop``), stamped from ``origin_ns`` on.

    ``origin_ns=None`` stamps the first sample with the wall clock (``time.time_ns``)
    at the moment the first run is ready, so a real-time publisher's stamps match the
    wall clock from its first message.
    """

    def __init__(
        self,
        vehicle: VehicleParams,
        runs: Sequence[Maneuver],
        sigma: SensorNoiseSigma,
        *,
        seed: int,
        origin_ns: int | None = None,
        loop: bool = False,
        decimation: int = 1,
        ground_truth: bool = True,
        imu: ImuMounting | None = None,
    ) -> None:
        if not runs:
            raise ValueError("SampleStream: no runs")
        if decimation < 1:
            raise ValueError(f"decimation must be >= 1, got {decimation}")
        self.vehicle = vehicle
        self.runs = list(runs)
        self.sigma = sigma
        self.seed = seed
        self.loop = loop
        self.decimation = decimation
        self.ground_truth = ground_truth
        self.imu = imu
        self.encoder = SampleEncoder(sigma)
        self._next_stamp_ns = origin_ns

    def __iter__(self) -> Iterator[RunChunk]:
        while True:
            for m in self.runs:
                yield self._run(m)
            if not self.loop:
                return

    def _run(self, m: Maneuver) -> RunChunk:
        result = simulate(self.vehicle, m)
        noisy = add_noise(
            exact_samples(result, imu=self.imu), self.sigma, run_seed(self.seed, m.name)
        )
        if self._next_stamp_ns is None:
            self._next_stamp_ns = time.time_ns()
        keep = np.arange(0, len(noisy), self.decimation)
        stamps = self._next_stamp_ns + keep.astype(np.int64) * DT_NS
        samples = _take(noisy, keep, stamps, self.ground_truth)
        self._next_stamp_ns = int(stamps[-1]) + round(RUN_PAUSE_S * 1e9)
        return RunChunk(m, samples, self.encoder.encode(samples))


def _take(
    s: SampleArrays, keep: np.ndarray, stamps: np.ndarray, ground_truth: bool
) -> SampleArrays:
    """Rows ``keep`` of ``s`` with new stamps; truth dropped unless ``ground_truth``."""
    names = SENSOR_CHANNELS + (TRUTH_CHANNELS if ground_truth and s.has_truth else ())
    return SampleArrays(stamp_ns=stamps, **{n: getattr(s, n)[keep] for n in names})
