"""The sim node's parameters: the table it declares (``--help`` lists it), the typed,
checked :class:`SimParams` built from the declared values, and the sample stream they
name (:func:`open_stream`).

Each default has one home: the node's settings in :class:`SimParams`, the noise
overrides (``sigma.*``) in :class:`SigmaOverride`, the manoeuvre family settings
(``maneuver.*``) in :class:`~.stream.ManeuverSpec`. The table takes its defaults from
those dataclasses and adds only names and descriptions.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any, Final

from sideslip_msgs_py.parameter_spec import ParameterSpec, help_text
from sideslip_msgs_py.sample import SensorNoiseSigma
from sideslip_msgs_py.timing import RATE_HZ
from sideslip_sim.imu_mounting import ImuMounting, ImuMountingError
from sideslip_sim.sensors import noise_profile
from sideslip_sim.stream import ManeuverSpec, SampleStream, select_runs
from sideslip_sim.vehicle import load_vehicle

STEP_HZ: Final = round(RATE_HZ)
"""Simulation steps per second; the publish rate is this or a divisor of it."""


class ParameterError(ValueError):
    """A parameter value the node cannot run with (message names the parameter)."""


@dataclass(frozen=True)
class SigmaOverride:
    """Sensor noise σ replacing the profile's (the ``sigma.*`` parameters), units as in
    :class:`~sideslip_msgs_py.sample.SensorNoiseSigma`; < 0 keeps the profile's value."""

    velocity_mps: float = -1.0
    acceleration_mps2: float = -1.0
    yaw_rate_radps: float = -1.0
    stl_m: float = -1.0

    def applied_to(self, profile: SensorNoiseSigma) -> SensorNoiseSigma:
        """``profile`` with every σ given here (>= 0) put in its place."""
        picked = {}
        for f in fields(self):
            value = getattr(self, f.name)
            picked[f.name] = getattr(profile, f.name) if value < 0.0 else value
        return SensorNoiseSigma(**picked)


@dataclass(frozen=True)
class ImuSpec:
    """Where the published IMU sits and which frame its accelerometer reads in (the
    ``imu.*`` parameters; :mod:`sideslip_sim.imu_mounting`)."""

    frame: str = "level"
    position_x_m: float = 0.0
    position_y_m: float = 0.0

    def mounting(self) -> ImuMounting:
        """The mounting; raises ParameterError naming the bad ``imu.*`` value."""
        try:
            return ImuMounting((self.position_x_m, self.position_y_m), self.frame)
        except ImuMountingError as err:
            raise ParameterError(f"imu.*: {err}") from None


_GROUPS: Final = {"sigma": SigmaOverride, "maneuver": ManeuverSpec, "imu": ImuSpec}
"""Nested parameter groups: field of :class:`SimParams` → dataclass of ``name.*``."""


@dataclass(frozen=True)
class SimParams:
    """The sim node's parameters, typed and checked (see :data:`PARAMETERS`)."""

    scenario: str = "scen1"
    vehicle: str = "paper_sedan"
    noise: str = "paper"
    sigma: SigmaOverride = field(default_factory=SigmaOverride)
    seed: int = 0
    randomized_count: int = 10
    rate_hz: float = RATE_HZ
    real_time_factor: float = 1.0
    """Simulated seconds per wall second; 0 = as fast as possible."""
    publish_clock: bool = False
    loop: bool = False
    ground_truth: bool = True
    wait_for_subscribers: int = 0
    wait_for_subscribers_timeout_s: float = 0.0
    """0 = wait without limit."""
    maneuver: ManeuverSpec = field(default_factory=ManeuverSpec)
    imu: ImuSpec = field(default_factory=ImuSpec)

    def __post_init__(self) -> None:
        self.imu.mounting()
        rtf = self.real_time_factor
        if not rtf >= 0.0:
            raise ParameterError(f"real_time_factor must be >= 0, got {rtf}")
        _decimation(self.rate_hz)
        timeout_s = self.wait_for_subscribers_timeout_s
        if not (math.isfinite(timeout_s) and timeout_s >= 0.0):
            raise ParameterError(
                f"wait_for_subscribers_timeout_s must be finite and >= 0, got {timeout_s}"
            )

    @property
    def decimation(self) -> int:
        """Publish every k-th simulation step (``rate_hz`` = :data:`STEP_HZ` / k)."""
        return _decimation(self.rate_hz)

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> SimParams:
        """From declared values (typed as their defaults), named as in :data:`PARAMETERS`;
        raises ParameterError naming the bad one."""
        kwargs: dict[str, Any] = {}
        for f in fields(cls):
            group = _GROUPS.get(f.name)
            if group is None:
                kwargs[f.name] = values[f.name]
            else:
                kwargs[f.name] = group(
                    **{g.name: values[f"{f.name}.{g.name}"] for g in fields(group)}
                )
        return cls(**kwargs)


def _decimation(rate_hz: float) -> int:
    k = round(STEP_HZ / rate_hz) if rate_hz > 0 else 0
    if k < 1 or abs(STEP_HZ / k - rate_hz) > 1e-9:
        raise ParameterError(f"rate_hz must be {STEP_HZ} or {STEP_HZ}/k, got {rate_hz}")
    return k


def open_stream(params: SimParams) -> SampleStream:
    """The samples ``params`` name: its runs, on its vehicle (read from file), with its
    noise. Raises ManeuverError, VehicleFileError, TirError or ValueError naming the
    bad parameter."""
    runs = select_runs(
        params.scenario, seed=params.seed, count=params.randomized_count, spec=params.maneuver
    )
    vehicle = load_vehicle(params.vehicle)
    sigma = params.sigma.applied_to(noise_profile(params.noise))
    return SampleStream(
        vehicle,
        runs,
        sigma,
        seed=params.seed,
        loop=params.loop,
        decimation=params.decimation,
        ground_truth=params.ground_truth,
        imu=params.imu.mounting(),
    )


def _defaults() -> dict[str, bool | int | float | str]:
    """Every declared parameter's default, read from the dataclasses that own it."""
    out: dict[str, bool | int | float | str] = {}
    node = SimParams()
    for f in fields(SimParams):
        value = getattr(node, f.name)
        if f.name in _GROUPS:
            out |= {f"{f.name}.{g.name}": getattr(value, g.name) for g in fields(value)}
        else:
            out[f.name] = value
    return out


_DEFAULTS: Final = _defaults()


def _spec(name: str, description: str) -> ParameterSpec:
    return ParameterSpec(name, _DEFAULTS[name], description)


PARAMETERS: Final = (
    _spec(
        "scenario",
        "What to drive: a Table 4 scenario (scen1..scen4), a preset (paper-test, "
        "paper-train, randomized) run by run, or a manoeuvre family (sine_steer, "
        "double_lane_change, sweep_steer, cornering, random_steer, step_steer, straight) "
        "set by the maneuver.* parameters.",
    ),
    _spec("vehicle", "Shipped vehicle name or vehicle YAML path."),
    _spec("noise", "Sensor noise profile: paper or none."),
    _spec("sigma.velocity_mps", "σ of X_v, Y_v [m/s]; < 0 = from the profile."),
    _spec("sigma.acceleration_mps2", "σ of X_a, Y_a [m/s²]; < 0 = profile."),
    _spec("sigma.yaw_rate_radps", "σ of the yaw rate [rad/s]; < 0 = profile."),
    _spec("sigma.stl_m", "σ of the steering rack travel [m]; < 0 = profile."),
    _spec("seed", "Noise (and randomized preset) seed; same seed, same data."),
    _spec("randomized_count", "Runs of the randomized preset."),
    _spec("rate_hz", "Publish rate [Hz]: 400 or a divisor (every k-th 2.5-ms step)."),
    _spec(
        "real_time_factor",
        "Simulated seconds per wall second: 1.0 = real time, 0 = as fast as possible.",
    ),
    _spec("publish_clock", "Publish /clock with the simulated time (for use_sim_time consumers)."),
    _spec("loop", "Start over after the last run instead of stopping."),
    _spec("ground_truth", "Also publish the ground-truth topics."),
    _spec(
        "wait_for_subscribers",
        "Hold the start until every published topic has this many subscribers (0 = start "
        "now). With only an estimator listening, set ground_truth false or it waits on.",
    ),
    _spec(
        "wait_for_subscribers_timeout_s",
        "Longest wait for those subscribers [s]; when it passes, the node logs which "
        "topics lack them and exits 1 without publishing (0 = wait without limit).",
    ),
    _spec("maneuver.duration_s", "Family runs: duration [s]."),
    _spec("maneuver.speed_kmh", "Family runs: initial speed [km/h]."),
    _spec("maneuver.torque_nm", "Family runs: total drive torque [N m]."),
    _spec("maneuver.stl_amplitude_m", "Family runs: steering amplitude [m]; 0 = automatic."),
    _spec("maneuver.mu", "Family runs: road friction coefficient."),
    _spec(
        "maneuver.bank_pct",
        "Family runs: road crossfall [%], > 0 falling to the right of the start heading "
        "(|bank| <= 10).",
    ),
    _spec(
        "imu.frame",
        "level: the CG acceleration in the horizontal frame, free of gravity (what the "
        "shipped models learnt); body: specific force in the body frame, gravity through "
        "roll and pitch in it, as a strapdown IMU reads (no orientation is published).",
    ),
    _spec("imu.position_x_m", "The IMU's place ahead of the CG [m] (its lever arm)."),
    _spec("imu.position_y_m", "The IMU's place left of the CG [m]."),
)


def help_page() -> str:
    """The node's ``--help``: what it is and every parameter."""
    return help_text(
        "sideslip-sim (ros2 run sideslip_sim sim_node): full-vehicle simulator "
        "publishing noisy sensor topics and ground truth.",
        [("Parameters", PARAMETERS)],
    )
