"""Manoeuvres: named, parameterised runs, and the per-step programs that drive the model.

A `Maneuver` is plain data (what a bag's metadata records). `build_program` turns it
into per-step inputs: an open-loop STL trace, a mask of the steps where the path-
following driver steers instead, the drive torque, and the reference path.

Sign convention: STL > 0 steers left (δ > 0, yaw rate > 0, a_y > 0). A signed
amplitude sets the first steering direction; ``side = -1`` turns a whole manoeuvre the
other way (its steering trace and its path mirrored left-right), for every family.

Amplitudes. Table 3 of the paper gives STL amplitudes for sine and sweep steer; the
vehicle file's STL ratio maps them to road-wheel angles (see README, "Steering scale").
Where the paper gives none (random steer) or a run is randomised, the amplitude is
chosen from the linear single-track model so that the steady-state lateral
acceleration is a stated fraction of μ·g at the run's initial speed: linear tyres at
small fractions, the nonlinear range near 0.8, never a command that could only spin
the car. For lane changes, the amplitude scales the lateral offset of the path
(0.10 m ↔ the ISO 3888-1 offset of 3.5 m), the course is stretched where following
it would need more than μ·g, and the driver produces the STL.

Road crossfall. ``bank_pct`` tilts the road: a plane whose fall line points to the
right of the run's start heading (> 0; roads drain towards their edge, about 2.5 % on a
straight) or to the left (< 0), with tan γ = bank_pct/100. It is a plane, not a road
that follows the car: once the car has turned by ψ, it meets the slope partly as a grade
(docs/vehicle-model.md). The tilt is ramped in over the first :data:`BANK_RAMP_S` (a
half-cosine), so that a run starts from the flat road's straight-line equilibrium
instead of a tyre force step, as a car enters a banked stretch.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sideslip_sim.driver import PathBuilder, iso_double_lane_change
from sideslip_sim.single_track import SingleTrack
from sideslip_sim.vehicle import GRAVITY_MPS2, VehicleParams

SCENARIOS = ("scen1", "scen2", "scen3", "scen4")

# Lead-in before open-loop steering starts [s]: the run starts in straight-line equilibrium.
LEAD_IN_S = 0.5
STEP_RAMP_S = 0.5  # a step steer's ramp to its held STL [s]
SINE_FREQUENCY_HZ = 0.5
SWEEP_START_HZ = 0.2
SWEEP_END_HZ = 2.0
RANDOM_CUTOFF_HZ = 1.0
# Lateral-acceleration fraction of μ·g for auto amplitudes and the right-angle turn radius.
AUTO_AY_FRACTION = 0.5
ISO_LANE_OFFSET_M = 3.5
DLC_REFERENCE_STL_M = 0.10
MAX_SPEED_KMH = 160.0
# Largest centreline lateral acceleration of a lane-change course, as a fraction of μ·g.
DLC_AY_FRACTION = 0.7
MAX_BANK_PCT = 10.0
"""Steeper crossfall is refused: the model keeps the normal load at m·g (cos γ ≥ 0.995
up to 10 %) and passenger roads stay below it (superelevation of curves up to ~8 %)."""
BANK_RAMP_S = 1.0


class ManeuverError(ValueError):
    """A manoeuvre has an unknown family/scenario or a value out of range."""


@dataclass(frozen=True)
class Maneuver:
    """One simulated run. Units: s, km/h (as the paper's tables), N m at the wheels, m."""

    name: str
    family: str
    duration_s: float
    speed_kmh: float
    torque_nm: float
    stl_amplitude_m: float = 0.0  # signed; 0 = automatic (see module docstring)
    mu: float = 1.0  # road friction relative to the tyre's test surface
    seed: int = 0  # random steer / randomised draws
    payload_kg: float = 0.0  # added at the sprung CG (randomised vehicle mass)
    scenario: str = ""  # Table 4 scenario id when family == "scenario"
    ay_fraction: float = AUTO_AY_FRACTION
    side: int = 1  # +1: as defined (most families open to the left); -1: mirrored
    bank_pct: float = 0.0  # road crossfall [%], > 0 falling to the right (module docstring)

    def __post_init__(self) -> None:
        if self.family not in FAMILIES:
            raise ManeuverError(f"{self.name}: unknown family {self.family!r}; known: {FAMILIES}")
        if self.family == "scenario" and self.scenario not in SCENARIOS:
            raise ManeuverError(
                f"{self.name}: unknown scenario {self.scenario!r}; known: {SCENARIOS}"
            )
        if not 0.0 < self.duration_s <= 600.0:
            raise ManeuverError(
                f"{self.name}: duration_s must be in (0, 600], got {self.duration_s}"
            )
        # RK4 at 2.5 ms stays stable on the tyres' relaxation modes (|λ| ~ speed/σ, σ down
        # to 0.05 m on a lightly loaded wheel) up to ~200 km/h: keep a margin.
        if not 0.0 <= self.speed_kmh <= MAX_SPEED_KMH:
            raise ManeuverError(
                f"{self.name}: speed_kmh must be in [0, {MAX_SPEED_KMH:.0f}], got {self.speed_kmh}"
            )
        if not 0.05 <= self.mu <= 1.5:
            raise ManeuverError(f"{self.name}: mu must be in [0.05, 1.5], got {self.mu}")
        if not 0.0 <= self.payload_kg <= 1000.0:
            raise ManeuverError(
                f"{self.name}: payload_kg must be in [0, 1000], got {self.payload_kg}"
            )
        if not 0.0 < self.ay_fraction <= 1.0:
            raise ManeuverError(
                f"{self.name}: ay_fraction must be in (0, 1], got {self.ay_fraction}"
            )
        if self.side not in (1, -1):
            raise ManeuverError(f"{self.name}: side must be 1 or -1, got {self.side!r}")
        if not abs(self.bank_pct) <= MAX_BANK_PCT:  # (NaN fails too)
            raise ManeuverError(
                f"{self.name}: bank_pct must be in [-{MAX_BANK_PCT:g}, {MAX_BANK_PCT:g}] %, "
                f"got {self.bank_pct}"
            )

    @property
    def speed_mps(self) -> float:
        return self.speed_kmh / 3.6

    def to_dict(self) -> dict[str, object]:
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class Program:
    """Per-step inputs for n steps: STL [m] where open loop, driver mask, torque [N m],
    the road's sin γ (signed as ``bank_pct``, ramped in)."""

    stl_open_m: np.ndarray
    use_driver: np.ndarray
    torque_nm: np.ndarray
    path_x_m: np.ndarray
    path_y_m: np.ndarray
    bank_sin: np.ndarray


def with_payload(vehicle: VehicleParams, payload_kg: float) -> VehicleParams:
    """The vehicle with payload added at the sprung CG; inertias scale with sprung mass."""
    if payload_kg == 0.0:
        return vehicle
    scale = (vehicle.sprung_mass_kg + payload_kg) / vehicle.sprung_mass_kg
    return dataclasses.replace(
        vehicle,
        sprung_mass_kg=vehicle.sprung_mass_kg + payload_kg,
        roll_inertia_kgm2=vehicle.roll_inertia_kgm2 * scale,
        pitch_inertia_kgm2=vehicle.pitch_inertia_kgm2 * scale,
        yaw_inertia_kgm2=vehicle.yaw_inertia_kgm2 * scale,
    )


def auto_stl_amplitude(
    vehicle: VehicleParams, model: SingleTrack, speed_mps: float, mu: float, fraction: float
) -> float:
    """STL [m] whose steady-state a_y is fraction·μ·g at speed (clamped to the lock)."""
    speed = max(speed_mps, 3.0)
    delta = fraction * mu * GRAVITY_MPS2 / model.lateral_acceleration_gain(speed)
    delta = min(delta, vehicle.max_road_wheel_angle_rad)
    return delta * vehicle.stl_per_road_wheel_angle_m_per_rad


def _time(n: int, dt: float) -> np.ndarray:
    return np.arange(n) * dt


def _sine(t: np.ndarray, amplitude: float, start_s: float, freq_hz: float) -> np.ndarray:
    tau = np.clip(t - start_s, 0.0, None)
    return np.where(t >= start_s, amplitude * np.sin(2.0 * np.pi * freq_hz * tau), 0.0)


def _sweep(t: np.ndarray, amplitude: float, start_s: float, end_s: float) -> np.ndarray:
    """Linear chirp from SWEEP_START_HZ to SWEEP_END_HZ between start_s and end_s."""
    span = max(end_s - start_s, 1e-6)
    tau = np.clip(t - start_s, 0.0, span)
    rate = (SWEEP_END_HZ - SWEEP_START_HZ) / span
    phase = 2.0 * np.pi * (SWEEP_START_HZ * tau + 0.5 * rate * tau * tau)
    return np.where(t >= start_s, amplitude * np.sin(phase), 0.0)


def _random(t: np.ndarray, amplitude: float, start_s: float, seed: int) -> np.ndarray:
    """Band-limited Gaussian steering: white noise low-passed at RANDOM_CUTOFF_HZ (a
    raised-cosine roll-off in the frequency domain), scaled so its peak is |amplitude|
    (a negative amplitude mirrors it)
    and faded in over one second after the lead-in."""
    rng = np.random.default_rng(seed)
    n = t.shape[0]
    dt = float(t[1] - t[0]) if n > 1 else 1.0
    spectrum = np.fft.rfft(rng.standard_normal(n))
    freq = np.fft.rfftfreq(n, dt)
    cutoff = RANDOM_CUTOFF_HZ
    gain = np.where(freq <= cutoff, 1.0, 0.0)
    band = (freq > cutoff) & (freq < 2.0 * cutoff)
    gain[band] = 0.5 * (1.0 + np.cos(np.pi * (freq[band] - cutoff) / cutoff))
    signal = np.fft.irfft(spectrum * gain, n)
    signal -= signal.mean()
    peak = np.max(np.abs(signal))
    signal = signal / peak * amplitude if peak > 0 else signal  # sign mirrors the trace
    fade = np.clip((t - start_s) / 1.0, 0.0, 1.0)
    return signal * fade


def _turn_radius(speed_mps: float, mu: float, fraction: float) -> float:
    return max(speed_mps**2 / (fraction * mu * GRAVITY_MPS2), 8.0)


def _cornering_path(
    builder: PathBuilder, speed_mps: float, mu: float, fraction: float, direction: float
) -> PathBuilder:
    radius = _turn_radius(speed_mps, mu, fraction)
    lead = max(5.0, 0.8 * speed_mps)
    return builder.straight(lead).arc(radius, direction * math.pi / 2.0)


def _dlc_length_scale(m: Maneuver, offset_m: float) -> float:
    """Stretch of the ISO course so that following its centreline at the initial speed
    needs at most μ·g: a cosine lane change of offset d over length L peaks at
    a = d·π²·u² / (2·L²). 1 where the ISO course is feasible (the 30-m change at μ = 1
    up to ~80 km/h); otherwise the course becomes as long as the friction requires,
    instead of one that no car can follow."""
    needed = abs(offset_m) * math.pi**2 * m.speed_mps**2 / (2.0 * 30.0**2)
    return max(1.0, math.sqrt(needed / (DLC_AY_FRACTION * m.mu * GRAVITY_MPS2)))


def _dlc_offset(amplitude_m: float) -> float:
    amp = amplitude_m if amplitude_m != 0.0 else DLC_REFERENCE_STL_M
    return ISO_LANE_OFFSET_M * amp / DLC_REFERENCE_STL_M


BuildFn = Callable[[Maneuver, VehicleParams, SingleTrack, np.ndarray], tuple]


def _build_straight(m, vehicle, model, t):
    return np.zeros_like(t), np.zeros(t.shape, bool), None


def _build_sine(m, vehicle, model, t):
    amp = m.stl_amplitude_m or auto_stl_amplitude(vehicle, model, m.speed_mps, m.mu, m.ay_fraction)
    return _sine(t, amp, LEAD_IN_S, SINE_FREQUENCY_HZ), np.zeros(t.shape, bool), None


def _build_sweep(m, vehicle, model, t):
    amp = m.stl_amplitude_m or auto_stl_amplitude(vehicle, model, m.speed_mps, m.mu, m.ay_fraction)
    return _sweep(t, amp, LEAD_IN_S, m.duration_s), np.zeros(t.shape, bool), None


def _build_random(m, vehicle, model, t):
    amp = m.stl_amplitude_m or auto_stl_amplitude(vehicle, model, m.speed_mps, m.mu, m.ay_fraction)
    return _random(t, amp, LEAD_IN_S, m.seed), np.zeros(t.shape, bool), None


def _build_step(m, vehicle, model, t):
    """Ramp to a constant STL over 0.5 s after the lead-in, then hold (ISO 7401 / 4138
    style): the steady-state cornering reference."""
    amp = m.stl_amplitude_m or auto_stl_amplitude(vehicle, model, m.speed_mps, m.mu, m.ay_fraction)
    ramp = np.clip((t - LEAD_IN_S) / STEP_RAMP_S, 0.0, 1.0)
    return amp * ramp, np.zeros(t.shape, bool), None


def _build_dlc(m, vehicle, model, t):
    offset = _dlc_offset(m.stl_amplitude_m)
    path = iso_double_lane_change(PathBuilder(), offset, _dlc_length_scale(m, offset))
    return np.zeros_like(t), np.ones(t.shape, bool), path


def _build_cornering(m, vehicle, model, t):
    direction = -1.0 if m.stl_amplitude_m < 0 else 1.0
    path = _cornering_path(PathBuilder(), m.speed_mps, m.mu, m.ay_fraction, direction)
    return np.zeros_like(t), np.ones(t.shape, bool), path


def _build_scenario(m, vehicle, model, t):
    """Table 4 test scenarios (their steering details are ours: the paper gives only the
    description, speed, torque and duration)."""
    course = ISO_LANE_OFFSET_M, _dlc_length_scale(m, ISO_LANE_OFFSET_M)
    if m.scenario == "scen1":  # DLC, then open-loop sine steer once the course is done
        builder = iso_double_lane_change(PathBuilder(), *course)
        switch_s = builder.length_m / max(m.speed_mps, 1.0)
        amp = m.stl_amplitude_m or 0.08
        return _sine(t, amp, switch_s, SINE_FREQUENCY_HZ), t < switch_s, builder
    if m.scenario == "scen2":  # DLC, a short straight, then a right-angle right turn
        builder = iso_double_lane_change(PathBuilder(), *course).straight(10.0)
        radius = _turn_radius(m.speed_mps, m.mu, m.ay_fraction)
        builder.arc(radius, -math.pi / 2.0)
        return np.zeros_like(t), np.ones(t.shape, bool), builder
    if m.scenario == "scen3":  # continuous sine steer
        amp = m.stl_amplitude_m or 0.09
        return _sine(t, amp, LEAD_IN_S, 0.4), np.zeros(t.shape, bool), None
    # scen4: random steer
    amp = m.stl_amplitude_m or auto_stl_amplitude(vehicle, model, m.speed_mps, m.mu, m.ay_fraction)
    return _random(t, amp, LEAD_IN_S, m.seed), np.zeros(t.shape, bool), None


_BUILDERS: dict[str, BuildFn] = {
    "straight": _build_straight,
    "double_lane_change": _build_dlc,
    "sine_steer": _build_sine,
    "sweep_steer": _build_sweep,
    "cornering": _build_cornering,
    "random_steer": _build_random,
    "step_steer": _build_step,
    "scenario": _build_scenario,
}
# The manoeuvre families, in the order above: one per builder, so a family cannot be
# accepted by Maneuver without a program to run it.
FAMILIES: tuple[str, ...] = tuple(_BUILDERS)


def build_program(m: Maneuver, vehicle: VehicleParams, model: SingleTrack, dt_s: float) -> Program:
    """Per-step inputs for the whole run (n = round(duration / dt) samples)."""
    n = round(m.duration_s / dt_s)
    t = _time(n, dt_s)
    stl, use_driver, builder = _BUILDERS[m.family](m, vehicle, model, t)
    if builder is not None:
        # Extend the path well past what the run can cover so the driver never runs out.
        reach = (m.speed_mps + 15.0) * m.duration_s + 50.0
        builder.straight(max(reach - builder.length_m, 20.0))
        path_x, path_y = builder.build()
    else:
        path_x, path_y = np.array([0.0, 1.0]), np.array([0.0, 0.0])
    bank = math.sin(math.atan(m.bank_pct / 100.0)) * _bank_ramp(t)
    if m.side < 0:  # the car is symmetric: the same manoeuvre driven the other way round
        # (on the mirrored road: a mirrored run is the exact mirror image of the other)
        stl, path_y, bank = -np.asarray(stl), -np.asarray(path_y), -bank
    return Program(
        stl_open_m=np.ascontiguousarray(stl, dtype=np.float64),
        use_driver=np.ascontiguousarray(use_driver, dtype=np.bool_),
        torque_nm=np.full(n, float(m.torque_nm)),
        path_x_m=np.ascontiguousarray(path_x, dtype=np.float64),
        path_y_m=np.ascontiguousarray(path_y, dtype=np.float64),
        bank_sin=np.ascontiguousarray(bank, dtype=np.float64),
    )


def _bank_ramp(t: np.ndarray) -> np.ndarray:
    """0 → 1 over :data:`BANK_RAMP_S` as a half-cosine (no jerk step at either end)."""
    phase = np.clip(t / BANK_RAMP_S, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * phase)
