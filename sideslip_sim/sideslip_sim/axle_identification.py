"""The UKF's axle curves identified from a car's own labelled recordings.

A short description (mass, wheelbase, CG position, steering ratio, ...) leaves the
tyres unknown, and without a lateral-velocity sensor the rear axle's cornering
stiffness is what sets β (docs/training.md, "With only a description"): the fleet's
typical tyres put the UKF of a described car at about twice the error of the UKF with
the car's true axles. A recording with a reference β (an INS, an optical sensor, a
simulation's truth) measures exactly what is missing. Per sample, with the single-track
quantities the UKF itself uses (:mod:`sideslip_estimator.backends.ukf_model`),

    v = u tan β,   δ = STL / ratio,
    α_f = δ − atan((v + a r)/u),   α_r = −atan((v − b r)/u),
    F_yf cos δ = (m a_y b + I_z ṙ)/L,   F_yr = (m a_y a − I_z ṙ)/L,

each axle's force is known against its slip angle, over whatever the car drove: the
effective axle characteristic (:mod:`sideslip_sim.axle_characteristics`) from the road
instead of from a model. The channels are low-pass filtered forwards and backwards
(zero phase: the recording is offline, and a causal filter would shift the forces
against the slip angles) and ṙ is the derivative of the filtered yaw rate.

The recordings come from roads of unknown friction. The UKF's axle model scales a
curve by road friction μ by similarity (peak and peak slip scale with μ, the cornering
stiffness does not), so the fit is that model's: per axle the Magic Formula's B, and per
recording one μ shared by both axles,

    F_y/F_z = μ_k D sin(C atan(B α/μ_k − E (B α/μ_k − atan(B α/μ_k)))),

with C, E and D = μ_peak kept from the starting file (the description's car): a run's
friction and the axle's peak only appear as their product, which the UKF estimates
online anyway. B sets the cornering stiffness B C D, the quantity that decides β in
every manoeuvre below the limit. Forces are divided by the static axle load and by the
longitudinal load transfer the UKF applies (F_z/F_z0 from a_x and the CG height).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from sideslip_sim.ukf_params import AxleMagicFormula
from sideslip_sim.vehicle import GRAVITY_MPS2


class IdentificationError(ValueError):
    """The recordings cannot identify the axles (too short, too little cornering)."""


@dataclass(frozen=True)
class RecordedRun:
    """One labelled recording, SI units, body frame at the CG, z up (ISO 8855).

    ``beta_rad`` is the reference sideslip angle atan2(v_y, v_x); the other channels are
    the car's sensors as recorded (noisy); ``stl_m`` is the steering rack travel."""

    name: str
    t_s: np.ndarray
    u_mps: np.ndarray
    beta_rad: np.ndarray
    yaw_rate_radps: np.ndarray
    ay_mps2: np.ndarray
    ax_mps2: np.ndarray
    stl_m: np.ndarray


@dataclass(frozen=True)
class IdentificationSettings:
    """How the points are made and which are used.

    cutoff_hz: low-pass corner of the zero-phase filter [Hz] (sensor noise against
        the bandwidth of driving).
    min_speed_mps: slower samples are left out (slip angles need a speed).
    max_beta_rad: samples beyond this |β| are left out (a spinning car is no axle curve).
    max_yaw_accel_radps2: samples with a larger |ṙ| are left out (inf: none): in
        transients roll, tyre lag and an inertia that is only the description's guess
        bend the points away from the steady curve.

    point_step_s: the filtered points are taken every this many seconds [s]: the filter
        has removed what lies between, and fewer points keep the fit fast.
    min_points: fewer usable points than this in all raise IdentificationError.
    min_slip_rad: at least ``min_points`` // 10 points must reach this |α| on each axle,
        or the recordings hold too little cornering to tell a stiffness.

    The defaults were chosen on 12 cars of the validation fleet (5 min of each car's
    own driving, scored on its validation runs; docs/training.md, "Axles from the car's
    own recordings"): the UKF's mean MAE 0.162° with the described file, 0.130° with
    every sample (2 Hz), 0.117 ± 0.001° with |ṙ| ≤ 0.1 rad/s² at 1, 2 or 4 Hz (4 Hz the
    lowest), 0.128° with the car's true effective axles.
    """

    cutoff_hz: float = 4.0
    min_speed_mps: float = 5.0
    max_beta_rad: float = math.radians(12.0)
    max_yaw_accel_radps2: float = 0.1
    point_step_s: float = 0.02
    min_points: int = 500
    min_slip_rad: float = math.radians(0.5)


@dataclass(frozen=True)
class RunPoints:
    """One recording's axle points: slip angles [rad], forces over the axle load [-]."""

    name: str
    alpha_front_rad: np.ndarray
    force_front: np.ndarray
    alpha_rear_rad: np.ndarray
    force_rear: np.ndarray


@dataclass(frozen=True)
class Identification:
    """What :func:`identify_axles` found.

    params: the starting file's parameters with ``mf_b_front`` and ``mf_b_rear`` replaced.
    stiffness_ratio_front, stiffness_ratio_rear: identified over starting cornering
        stiffness (B C D) of each axle [-].
    run_friction: the fitted road friction of each recording [-] (only meaningful for
        runs that came near the limit; a run in the linear range leaves it free).
    points: points used per axle.
    rms_front, rms_rear: RMS of the fit's residual force over the axle load [-].
    """

    params: dict[str, float | str]
    stiffness_ratio_front: float
    stiffness_ratio_rear: float
    run_friction: dict[str, float]
    points: int
    rms_front: float
    rms_rear: float


def _smooth(x: np.ndarray, rate_hz: float, cutoff_hz: float) -> np.ndarray:
    from scipy.signal import butter, sosfiltfilt

    sos = butter(2, cutoff_hz, fs=rate_hz, output="sos")
    return sosfiltfilt(sos, x)


def run_points(
    run: RecordedRun, params: Mapping[str, float | str], settings: IdentificationSettings
) -> RunPoints:
    """The axle points of one recording (see module), with the nominal vehicle of
    ``params`` (a ``ukf`` params mapping: mass, yaw inertia, CG position and height,
    steering ratio, and the axle curves)."""
    t = np.asarray(run.t_s, dtype=float)
    empty = np.zeros(0)
    if t.size < 2:
        return RunPoints(run.name, empty, empty, empty, empty)
    rate_hz = 1.0 / float(np.median(np.diff(t)))
    if settings.cutoff_hz >= 0.5 * rate_hz:
        raise IdentificationError(
            f"{run.name}: recorded at {rate_hz:.4g} Hz, too slow for a {settings.cutoff_hz:g}-Hz "
            f"low-pass (needs more than {2 * settings.cutoff_hz:g} Hz)"
        )
    # sosfiltfilt pads each end with a few samples; runs this short give no points.
    if t.size < 30:
        return RunPoints(run.name, empty, empty, empty, empty)
    m = float(params["mass_kg"])
    iz = float(params["yaw_inertia_kgm2"])
    a, b = float(params["cg_to_front_axle_m"]), float(params["cg_to_rear_axle_m"])
    h = float(params["cg_height_m"])
    ratio = float(params["stl_per_road_wheel_angle_m_per_rad"])
    length = a + b
    fz_front = m * GRAVITY_MPS2 * b / length
    fz_rear = m * GRAVITY_MPS2 * a / length

    def f(x: np.ndarray) -> np.ndarray:
        return _smooth(np.asarray(x, dtype=float), rate_hz, settings.cutoff_hz)

    u, beta, r = f(run.u_mps), f(run.beta_rad), f(run.yaw_rate_radps)
    a_y, a_x, delta = f(run.ay_mps2), f(run.ax_mps2), f(run.stl_m) / ratio
    r_dot = np.gradient(r, t)
    keep = (
        (u > settings.min_speed_mps)
        & (np.abs(beta) < settings.max_beta_rad)
        & (np.abs(r_dot) <= settings.max_yaw_accel_radps2)
    )
    every = max(1, round(settings.point_step_s * rate_hz))
    thin = np.zeros_like(keep)
    thin[::every] = True
    keep &= thin
    u, beta, r, a_y, a_x = u[keep], beta[keep], r[keep], a_y[keep], a_x[keep]
    delta, r_dot = delta[keep], r_dot[keep]
    v = u * np.tan(beta)
    # The UKF scales each axle's curve by F_z/F_z0 with the longitudinal load transfer.
    shift = m * h / length * a_x
    load_front = np.maximum(1.0 - shift / fz_front, 0.2)
    load_rear = np.maximum(1.0 + shift / fz_rear, 0.2)
    alpha_f = delta - np.arctan((v + a * r) / u)
    alpha_r = -np.arctan((v - b * r) / u)
    force_f = (m * a_y * b + iz * r_dot) / length / np.cos(delta) / (fz_front * load_front)
    force_r = (m * a_y * a - iz * r_dot) / length / (fz_rear * load_rear)
    return RunPoints(run.name, alpha_f, force_f, alpha_r, force_r)


def _on_road(curve: AxleMagicFormula, alpha: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """The axle's force over its load on a road of friction ``mu`` (similarity, as the UKF
    applies it: μ·F(α/μ))."""
    return mu * curve.force_n(alpha / mu, 1.0)


def identify_axles(
    runs: Sequence[RecordedRun],
    start: Mapping[str, float | str],
    settings: IdentificationSettings | None = None,
) -> Identification:
    """Each axle's B (and each recording's road μ) fitted to the recordings' points,
    starting from the ``ukf`` params ``start`` (the described car's file); see module.

    Raises IdentificationError when the recordings give fewer than
    ``settings.min_points`` points or too little cornering on an axle."""
    from scipy.optimize import least_squares

    settings = settings or IdentificationSettings()
    points = [run_points(run, start, settings) for run in runs]
    points = [p for p in points if p.alpha_front_rad.size]
    total = sum(p.alpha_front_rad.size for p in points)
    if total < settings.min_points:
        raise IdentificationError(
            f"{total} usable points in {len(runs)} recording(s), at least "
            f"{settings.min_points} needed: record more driving above "
            f"{settings.min_speed_mps:g} m/s"
        )
    af = np.concatenate([p.alpha_front_rad for p in points])
    ff = np.concatenate([p.force_front for p in points])
    ar = np.concatenate([p.alpha_rear_rad for p in points])
    fr = np.concatenate([p.force_rear for p in points])
    for axle, alpha in (("front", af), ("rear", ar)):
        cornering = int(np.count_nonzero(np.abs(alpha) >= settings.min_slip_rad))
        if cornering < settings.min_points // 10:
            raise IdentificationError(
                f"{axle} axle: {cornering} points at a slip angle of "
                f"{math.degrees(settings.min_slip_rad):g}° or more, at least "
                f"{settings.min_points // 10} needed: record some cornering"
            )
    run_index = np.concatenate([np.full(p.alpha_front_rad.size, k) for k, p in enumerate(points)])
    keys = ("mf_b", "mf_c", "mf_e", "mu_peak")
    front, rear = (
        AxleMagicFormula(*(float(start[f"{k}_{axle}"]) for k in keys)) for axle in ("front", "rear")
    )
    b0 = np.array([front.b, rear.b])

    def residual(p: np.ndarray) -> np.ndarray:
        mu = p[2:][run_index]
        return np.concatenate(
            [
                _on_road(replace(front, b=p[0]), af, mu) - ff,
                _on_road(replace(rear, b=p[1]), ar, mu) - fr,
            ]
        )

    n = len(points)
    x0 = np.concatenate([b0, np.ones(n)])
    # Each residual depends on its axle's B and its recording's μ only: a sparse Jacobian
    # keeps hours of driving in many recordings cheap (dense it grows with both).
    from scipy.sparse import lil_matrix

    sparsity = lil_matrix((2 * af.size, 2 + n), dtype=np.int8)
    rows = np.arange(af.size)
    sparsity[rows, 0] = 1
    sparsity[rows + af.size, 1] = 1
    sparsity[rows, 2 + run_index] = 1
    sparsity[rows + af.size, 2 + run_index] = 1
    fit = least_squares(
        residual,
        x0,
        jac_sparsity=sparsity,
        bounds=(
            np.concatenate([0.2 * b0, np.full(n, 0.1)]),
            np.concatenate([5.0 * b0, np.full(n, 1.5)]),
        ),
        x_scale=np.concatenate([b0, np.ones(n)]),
    )
    res = fit.fun
    params = dict(start)
    params["mf_b_front"] = float(f"{fit.x[0]:.5g}")
    params["mf_b_rear"] = float(f"{fit.x[1]:.5g}")
    return Identification(
        params=params,
        stiffness_ratio_front=float(fit.x[0] / b0[0]),
        stiffness_ratio_rear=float(fit.x[1] / b0[1]),
        run_friction={p.name: float(mu) for p, mu in zip(points, fit.x[2:], strict=True)},
        points=total,
        rms_front=float(np.sqrt(np.mean(res[: af.size] ** 2))),
        rms_rear=float(np.sqrt(np.mean(res[af.size :] ** 2))),
    )
