"""Unscented Kalman filter on a nonlinear single-track model with Magic Formula axles.

The model-based baseline that production stacks use (and the paper's future work). Like
``single_track`` it reads only what a production car measures (the ``measurable``
channels: X_v, X_a, Y_a, ψ̇, STL; never Y_v) and the vehicle's nominal parameters
(:class:`UkfParams`, written by ``python -m sideslip_sim.ukf_params VEHICLE``).

State (REP-103, body frame at the CG), in this order (:attr:`UkfBackend.state_names`):

    v_x  [m/s]    longitudinal velocity
    v_y  [m/s]    lateral velocity
    ψ̇    [rad/s]  yaw rate
    α_f, α_r [rad]  relaxed axle slip angles (with ``tyre_relaxation``)
    μ    [-]      road friction relative to the tyre's test surface: a random walk
                  that returns to ``friction_initial`` with time constant
                  ``friction_memory_s`` (with ``estimate_friction``; else fixed there)
    d_y  [m/s²]   lateral disturbance (with ``estimate_disturbance``): an acceleration
                  the tyres do not give, gravity's share on a banked road and the
                  model's own lateral-force error; it drives v̇_y = F_y/m − ψ̇ v_x + d_y
                  and is in the measured a_y = F_y/m + d_y (the IMU reads the car's
                  acceleration, docs/evaluation/road-bank), a random walk returning to 0
                  with time constant ``disturbance_memory_s``

Inputs: δ = STL / steering ratio (mean road-wheel angle) and a_x = X_a; the model
(:mod:`.ukf_model`) gives the state's derivative, and (ψ̇, a_y, v_x) to compare with
the yaw rate, Y_a and X_v.

Each step integrates with Heun's method (inputs linear between the two samples) over dt
from the stamps; dt = 0 (a repeated stamp) skips the prediction, a gap is integrated in
sub-steps of at most :data:`MAX_SUBSTEP_S`, and one longer than :data:`MAX_GAP_S` (or
a stamp going back) restarts the filter. β̂ = atan2(v_y, v_x) and its variance is J P Jᵀ with
J = ∂β/∂(v_x, v_y) = (−v_y, v_x)/(v_x² + v_y²).

Filter algebra: filterpy's :class:`~filterpy.kalman.UnscentedKalmanFilter` with Van der
Merwe's scaled sigma points (α = 1, β = 2, κ = 0: all weights positive, 2n + 1 points).
Ours are only: the square root is numpy's Cholesky (upper factor; filterpy's default,
scipy's, checks its input and costs more), P is symmetrised after each update (P − K S Kᵀ
drifts asymmetric over millions of steps), the sigma points are redrawn where filterpy's
predict would have (a restart, a repeated stamp), and the model runs on all sigma points
in one call (numpy arrays, one element per point) where filterpy calls it once per point
(:func:`_batch_filter_class`; the estimates agree to 1e-16 rad). A non-finite state or
covariance, or one that is not positive definite, restarts the filter and gives no
estimate.

Cost per ``update`` (``bench/tools/ukf_update_cost.py``: one core of the 2-core
development VM, Python 3.11, numpy 2.4, filterpy 2.0.0, the defaults: 6 states, 13 sigma
points; an 8-s sine steer of paper_sedan near the limit with the paper's noise, the best
of three passes, the two versions run alternately on the otherwise idle machine,
2026-12-07): 0.196–0.202 ms with the model on all sigma points at once, 0.265–0.272 ms
with filterpy's call per point in Python floats (the model alone was about 0.10 ms of
it: 13 Heun steps at 6 µs, 13 measurement predictions at 1.6 µs). The rest is filterpy's
sigma points, transforms and algebra; the node's budget is 2.5 ms per sample. numpy's
Cholesky takes 3.7 µs against scipy's 6.3 µs, twice a step.

filterpy (and scipy) are imported when the back-end is built, never when this module is
imported, so the registry and the other back-ends work without them.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.features import channel_indices
from sideslip_msgs_py.model_inputs import OBSERVER_COLUMNS
from sideslip_msgs_py.timing import STEP_S

from .base import BackendError, Estimate, parameter_values, positive_values
from .ukf_model import MIN_VX_MPS, SingleTrackMagicFormula, UkfParams
from .ukf_parameters import TUNED_PARAMETERS, UKF_PARAMETERS

X_V, X_A, Y_A, YAW_RATE, STL = channel_indices(
    ("x_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m")
)

_BASE_STATE: Final = ("v_x_mps", "v_y_mps", "yaw_rate_radps")
_NO_OBSERVATION: Final = (math.nan,) * len(OBSERVER_COLUMNS)
MAX_SUBSTEP_S: Final = 0.005
"""Longest integration step [s]: a longer dt (dropped samples) is split into sub-steps."""
MAX_GAP_S: Final = 0.5
"""A dt longer than this [s] restarts the filter: the state is stale, not predictable."""
# The prior at a (re)start: β 2° (as v_y = β v_x, so that a restart at walking pace does
# not put sigma points at absurd slip angles), ψ̇ near the measured one, slips near the
# kinematic ones.
_INITIAL_SIGMA_BETA_RAD: Final = 0.035
_INITIAL_SIGMA_R_RADPS: Final = 0.05
_INITIAL_SIGMA_SLIP_RAD: Final = 0.02


def _upper_cholesky(a: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """U with UᵀU = a (filterpy's convention: sigma points from the rows of U)."""
    return np.linalg.cholesky(a).T


@functools.cache
def _batch_filter_class(kalman: Any) -> type:
    """filterpy's :class:`~filterpy.kalman.UnscentedKalmanFilter` with its ``fx`` and
    ``hx`` called once on all sigma points (one row each) instead of once per point, and
    the cross covariance as one product; its algebra is otherwise filterpy's own. Built
    on first use: filterpy is imported only when a filter is."""

    class BatchUnscentedKalmanFilter(kalman.UnscentedKalmanFilter):  # type: ignore[misc]
        def compute_process_sigmas(self, dt: float, fx: Any = None, **fx_args: Any) -> None:
            sigmas = self.points_fn.sigma_points(self.x, self.P)
            self.sigmas_f = (fx or self.fx)(sigmas, dt, **fx_args)

        def update(self, z: Any, R: Any = None, UT: Any = None, hx: Any = None, **hx_args: Any):
            # filterpy maps hx over sigmas_f row by row, in order: hand it the rows
            # computed at once.
            rows = iter((hx or self.hx)(self.sigmas_f, **hx_args))
            super().update(z, R, UT, hx=lambda _point: next(rows))

        def cross_variance(self, x: Any, z: Any, sigmas_f: Any, sigmas_h: Any) -> Any:
            # Σ_i W_i (χ_i − x)(γ_i − z)ᵀ; filterpy's residuals are plain differences.
            return (self.Wc[:, None] * (sigmas_f - x)).T @ (sigmas_h - z)

    return BatchUnscentedKalmanFilter


def _import_filterpy() -> Any:
    try:
        from filterpy import kalman
    except ImportError as err:
        msg = f"ukf: needs filterpy (pip install filterpy scipy): {err}"
        raise BackendError(msg) from None
    return kalman


class UkfBackend:
    """Unscented Kalman filter on the Magic Formula single-track model (module docstring)."""

    name = "ukf"
    sample_period_s = None  # any rate: works on the stamps
    channels = ("x_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m")
    caveats: tuple[str, ...] = ()
    parameters = UKF_PARAMETERS

    def __init__(self, values: Mapping[str, object], window_steps: int) -> None:
        del window_steps  # recursive: it reads the newest row only
        v = parameter_values(self.name, self.parameters, values)
        self.params = UkfParams.load(str(v["params_file"]))
        sig = positive_values(
            self.name,
            v,
            (
                *TUNED_PARAMETERS,
                "friction_initial",
                "friction_initial_sigma",
                "friction_memory_s",
                "disturbance_sigma_mps2",
                "disturbance_memory_s",
                "min_speed_mps",
            ),
        )
        self.min_speed = sig["min_speed_mps"]
        self.friction_initial = sig["friction_initial"]
        self.friction_memory = sig["friction_memory_s"]
        self.relaxation = bool(v["tyre_relaxation"])
        self.estimate_friction = bool(v["estimate_friction"])
        self.disturbance_memory = sig["disturbance_memory_s"]
        self.model = SingleTrackMagicFormula(self.params)
        self._steer_ratio = self.params.stl_per_road_wheel_angle_m_per_rad

        # State layout: v_x, v_y, ψ̇, then the optional relaxed slips and μ.
        names = list(_BASE_STATE)
        q = [sig[k] for k in TUNED_PARAMETERS[3:6]]
        p0 = [sig["longitudinal_velocity_sigma_mps"], 1.0]  # v_y: scaled at each start
        p0.append(_INITIAL_SIGMA_R_RADPS)
        if self.relaxation:
            names += ["slip_front_rad", "slip_rear_rad"]
            q += [sig["process_sigma_slip_rad_per_sqrt_s"]] * 2
            p0 += [_INITIAL_SIGMA_SLIP_RAD] * 2
        self._i_mu = len(names) if self.estimate_friction else -1
        if self.estimate_friction:
            names.append("road_friction")
            q.append(sig["process_sigma_friction_per_sqrt_s"])
            p0.append(sig["friction_initial_sigma"])
        self._i_dist = len(names) if bool(v["estimate_disturbance"]) else -1
        if self._i_dist >= 0:
            names.append("lateral_disturbance_mps2")
            # An Ornstein-Uhlenbeck walk whose stationary 1-σ is disturbance_sigma_mps2.
            q.append(sig["disturbance_sigma_mps2"] * math.sqrt(2.0 / self.disturbance_memory))
            p0.append(sig["disturbance_sigma_mps2"])
        self.state_names = tuple(names)
        n = len(names)
        self._q_rate = np.square(q)
        self._p0 = np.diag(np.square(p0))
        kalman = _import_filterpy()
        points = kalman.MerweScaledSigmaPoints(
            n, alpha=1.0, beta=2.0, kappa=0.0, sqrt_method=_upper_cholesky
        )
        self._ukf = _batch_filter_class(kalman)(
            dim_x=n, dim_z=3, dt=STEP_S, hx=self._hx, fx=self._fx, points=points
        )
        self._ukf.R = np.diag(np.square([sig[k] for k in TUNED_PARAMETERS[:3]]))
        self.model_id = f"ukf({self.params.name})"
        self.reset()

    # --- model functions handed to filterpy ------------------------------------------------
    # Each takes all sigma points at once, one row per point (:func:`_batch_filter_class`).
    def _derivative(
        self, x: npt.NDArray[np.float64], delta: float, a_x: float
    ) -> npt.NDArray[np.float64]:
        """dx/dt of each row's state (layout of :attr:`state_names`)."""
        model = self.model
        v_x, v_y, r = x[:, 0], x[:, 1], x[:, 2]
        mu = x[:, self._i_mu] if self._i_mu >= 0 else self.friction_initial
        kin_f, kin_r = model.slip_angles(v_x, v_y, r, delta)
        if self.relaxation:
            alpha_f, alpha_r = x[:, 3], x[:, 4]
        else:
            alpha_f, alpha_r = kin_f, kin_r
        f_front, f_rear = model.forces(alpha_f, alpha_r, mu, a_x)
        dx = np.empty_like(x)
        dx[:, 0], dx[:, 1], dx[:, 2] = model.accelerations(v_x, v_y, r, f_front, f_rear, delta, a_x)
        if self.relaxation:
            # Pacejka's first-order contact model, as the simulator's tyres relax.
            speed = np.maximum(v_x, MIN_VX_MPS)
            dx[:, 3] = speed / model.relaxation_front_m * (kin_f - alpha_f)
            dx[:, 4] = speed / model.relaxation_rear_m * (kin_r - alpha_r)
        if self._i_mu >= 0:
            # A random walk that slowly forgets (Ornstein-Uhlenbeck): bounded uncertainty.
            dx[:, self._i_mu] = (self.friction_initial - mu) / self.friction_memory
        if self._i_dist >= 0:
            # It moves the car sideways; the tyres do not carry it.
            d_y = x[:, self._i_dist]
            dx[:, 1] += d_y
            dx[:, self._i_dist] = -d_y / self.disturbance_memory
        return dx

    def _fx(
        self,
        x: npt.NDArray[np.float64],
        dt: float,
        delta0: float = 0.0,
        delta1: float = 0.0,
        ax0: float = 0.0,
        ax1: float = 0.0,
    ) -> npt.NDArray[np.float64]:
        """Heun step of dt [s] of each row, inputs going linearly from (δ0, a_x0) to
        (δ1, a_x1)."""
        k1 = self._derivative(x, delta0, ax0)
        k2 = self._derivative(x + dt * k1, delta1, ax1)
        return x + (0.5 * dt) * (k1 + k2)

    def _hx(self, x: npt.NDArray[np.float64], delta: float, a_x: float) -> npt.NDArray[np.float64]:
        """Predicted (ψ̇, a_y, v_x) of each row's state; a_y = (F_yf cos δ + F_yr)/m."""
        v_x, v_y, r = x[:, 0], x[:, 1], x[:, 2]
        mu = x[:, self._i_mu] if self._i_mu >= 0 else self.friction_initial
        if self.relaxation:
            alpha_f, alpha_r = x[:, 3], x[:, 4]
        else:
            alpha_f, alpha_r = self.model.slip_angles(v_x, v_y, r, delta)
        f_front, f_rear = self.model.forces(alpha_f, alpha_r, mu, a_x)
        a_y = (f_front * math.cos(delta) + f_rear) / self.model.m
        if self._i_dist >= 0:
            a_y = a_y + x[:, self._i_dist]  # the IMU reads the car's acceleration, all of it
        return np.stack([r, a_y, v_x], axis=1)

    # --- Backend protocol ------------------------------------------------------------------
    def reset(self) -> None:
        self._started = False
        self._last_stamp = 0
        self._last_inputs = (0.0, 0.0)

    def _start(self, z: npt.NDArray[np.float64], delta: float) -> None:
        v_x, r = float(z[2]), float(z[0])
        x = [v_x, 0.0, r]
        if self.relaxation:
            x += [float(a) for a in self.model.slip_angles(v_x, 0.0, r, delta)]
        if self._i_mu >= 0:
            x.append(self.friction_initial)
        if self._i_dist >= 0:
            x.append(0.0)
        self._ukf.x = np.array(x)
        self._ukf.P = self._p0.copy()
        self._ukf.P[1, 1] = (_INITIAL_SIGMA_BETA_RAD * v_x) ** 2
        self._redraw_sigma_points()
        self._started = True

    def _redraw_sigma_points(self) -> None:
        """Sigma points of the current (x, P) for the next update. predict() ends with
        this; a (re)start or a repeated stamp has no predict, and filterpy's update would
        otherwise use the previous prediction's points."""
        ukf = self._ukf
        ukf.sigmas_f = ukf.points_fn.sigma_points(ukf.x, ukf.P)

    def update(
        self, rows: npt.NDArray[np.float64], stamps_ns: npt.NDArray[np.int64]
    ) -> Estimate | None:
        row = rows[-1]
        stamp = int(stamps_ns[-1])
        u = float(row[X_V])
        if not u >= self.min_speed:  # NaN too
            self.reset()
            return None
        z = np.array([row[YAW_RATE], row[Y_A], u])
        inputs = (float(row[STL]) / self._steer_ratio, float(row[X_A]))
        try:
            # A sigma point driven non-finite ends in the checks that restart the filter;
            # numpy's warnings on the way would only repeat that, at every sample.
            with np.errstate(all="ignore"):
                self._step(z, inputs, stamp)
        except (np.linalg.LinAlgError, ValueError, ZeroDivisionError, OverflowError):
            # P lost positive definiteness, or the model met a non-finite number.
            self.reset()
            return None
        return self._estimate()

    def _step(self, z: npt.NDArray[np.float64], inputs: tuple[float, float], stamp: int) -> None:
        ukf = self._ukf
        dt = (stamp - self._last_stamp) * 1e-9
        if not self._started or not 0.0 <= dt <= MAX_GAP_S:  # also a stamp going back
            self._start(z, inputs[0])
        elif dt > 0.0:
            (delta0, ax0), (delta1, ax1) = self._last_inputs, inputs
            steps = math.ceil(dt / MAX_SUBSTEP_S - 1e-9)
            h = dt / steps
            ukf.Q = np.diag(self._q_rate * h)
            for i in range(steps):
                f0, f1 = i / steps, (i + 1) / steps
                ukf.predict(
                    dt=h,
                    delta0=delta0 + f0 * (delta1 - delta0),
                    delta1=delta0 + f1 * (delta1 - delta0),
                    ax0=ax0 + f0 * (ax1 - ax0),
                    ax1=ax0 + f1 * (ax1 - ax0),
                )
        else:  # the same stamp again: a second measurement, no time to predict over
            self._redraw_sigma_points()
        self._last_stamp = stamp
        self._last_inputs = inputs
        ukf.update(z, delta=inputs[0], a_x=inputs[1])
        ukf.P = 0.5 * (ukf.P + ukf.P.T)

    def _estimate(self) -> Estimate | None:
        x, p = self._ukf.x, self._ukf.P
        v_x, v_y = float(x[0]), float(x[1])
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(p)) and v_x > 0.0):
            self.reset()
            return None
        j = np.array([-v_y, v_x]) / (v_x * v_x + v_y * v_y)
        variance = float(j @ p[:2, :2] @ j)
        if not (math.isfinite(variance) and variance >= 0.0):
            self.reset()
            return None
        return Estimate(math.atan2(v_y, v_x), variance)

    @property
    def state(self) -> dict[str, float]:
        """The filter's current state by name (:attr:`state_names`), for tools and tests."""
        return {n: float(v) for n, v in zip(self.state_names, self._ukf.x, strict=True)}

    def observer_row(self, estimate: Estimate | None) -> tuple[float, ...]:
        """What a model anchored on this filter reads after an update that gave
        ``estimate``, in :data:`~sideslip_msgs_py.model_inputs.OBSERVER_COLUMNS` order:
        β̂ [rad], road μ̂ [-] (``friction_initial`` without the friction state), and the
        innovations of the yaw rate [rad/s] and a_y [m/s²]; NaN for no estimate."""
        if estimate is None:
            return _NO_OBSERVATION
        mu = self.friction_initial if self._i_mu < 0 else float(self._ukf.x[self._i_mu])
        innovation = self._ukf.y
        return (estimate.beta_rad, mu, float(innovation[0]), float(innovation[1]))

    @property
    def state_sigma(self) -> dict[str, float]:
        """1-σ of each state (square roots of P's diagonal), by name."""
        sigma = np.sqrt(np.diag(self._ukf.P))
        return {n: float(v) for n, v in zip(self.state_names, sigma, strict=True)}
