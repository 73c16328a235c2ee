"""Run one manoeuvre through the full-vehicle model: pure, no ROS, no I/O.

The step loop (driver, steering, RK4) is compiled with numba so that one vehicle runs
hundreds of times faster than real time on one core; `simulate` is the Python entry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from sideslip_msgs_py.timing import STEP_S
from sideslip_sim import dynamics as dyn
from sideslip_sim.axle_tires import axle_tires
from sideslip_sim.driver import DriverParams, pure_pursuit
from sideslip_sim.maneuvers import Maneuver, build_program, with_payload
from sideslip_sim.single_track import SingleTrack
from sideslip_sim.tire import TireParams, load_tire
from sideslip_sim.vehicle import VehicleParams

DT_S = STEP_S  # 400 Hz, the paper's step (the contract's, sideslip_msgs_py.timing)
_HANDOVER_STEPS = 120  # 0.3 s blend when the driver hands over to open-loop steering

# Output channels of the compiled loop, one row per sample.
O_U, O_V, O_R, O_AX, O_AY, O_STL, O_STL_RATE = 0, 1, 2, 3, 4, 5, 6
O_X, O_Y, O_PSI, O_PHI, O_THETA, O_DELTA = 7, 8, 9, 10, 11, 12
O_FZ = 13  # 4 corners
O_OMEGA = 17  # 4 corners
O_GX, O_GY = 21, 22  # gravity's share in the road plane (0 on a level road)
N_OUT = 23


class SimulationError(RuntimeError):
    """The integration produced a non-finite state (a model or input defect)."""


@dataclass(frozen=True)
class SimResult:
    """Exact signals of one run, one row per 2.5-ms sample, SI units, vehicle frame at CG.

    t_s[k] = k·dt. a_x/a_y are the CG accelerations in the horizontal vehicle frame,
    so v̇ = a_y − r·u holds. fz_n and omega_radps have one column per corner (FL, FR, RL, RR).
    gravity_x/y_mps2: gravity's share in the road plane in the vehicle frame (a banked
    road's, :mod:`.dynamics`; 0 on a level road): what the tyres carry is a − g.
    """

    maneuver: Maneuver
    vehicle_name: str
    t_s: np.ndarray
    u_mps: np.ndarray
    v_mps: np.ndarray
    yaw_rate_radps: np.ndarray
    ax_mps2: np.ndarray
    ay_mps2: np.ndarray
    stl_m: np.ndarray
    stl_rate_mps: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    psi_rad: np.ndarray
    roll_rad: np.ndarray
    pitch_rad: np.ndarray
    delta_rad: np.ndarray
    fz_n: np.ndarray
    omega_radps: np.ndarray
    gravity_x_mps2: np.ndarray
    gravity_y_mps2: np.ndarray

    @property
    def beta_rad(self) -> np.ndarray:
        """Sideslip angle β = atan2(v, u) at the CG [rad]."""
        return np.arctan2(self.v_mps, self.u_mps)

    def __len__(self) -> int:
        return int(self.t_s.shape[0])


@njit(cache=True, error_model="numpy")
def _run(
    x: np.ndarray,
    carry: np.ndarray,
    k_start: int,
    k_end: int,
    p: np.ndarray,
    tc: np.ndarray,
    dt: float,
    stl_open: np.ndarray,
    use_driver: np.ndarray,
    torque: np.ndarray,
    mu: float,
    bank_sin: np.ndarray,
    path_x: np.ndarray,
    path_y: np.ndarray,
    driver_cfg: np.ndarray,
    out: np.ndarray,
) -> int:
    """Integrate steps k_start..k_end-1 from state x (in place), writing out[k - k_start].

    carry = [path index, previous STL, hand-over offset, hand-over steps left] links
    consecutive calls, so a batch run and a node stepping one sample per call go through
    the same compiled code. Returns -1, or the first step whose outputs are not finite.
    """
    k1 = np.empty(dyn.N_STATE)
    aux = np.empty(dyn.N_AUX)
    work = np.empty((5, dyn.N_STATE))
    steer = np.empty(dyn.N_STEER)
    wheel_torque = np.empty(4)
    ratio = p[dyn.P_STL_RATIO]
    wheelbase = p[dyn.P_A] + p[dyn.P_B]
    max_stl_step = driver_cfg[2] * ratio * dt
    lock_stl = p[dyn.P_MAX_DELTA] * ratio
    path_index = int(carry[0])
    stl_prev = carry[1]
    handover = carry[2]
    handover_left = int(carry[3])
    for k in range(k_start, k_end):
        if use_driver[k]:
            delta_cmd, path_index = pure_pursuit(
                x[dyn.S_X],
                x[dyn.S_Y],
                x[dyn.S_PSI],
                x[dyn.S_U],
                wheelbase,
                p[dyn.P_B],
                path_x,
                path_y,
                path_index,
                driver_cfg,
            )
            stl = delta_cmd * ratio
            # Human-like steering-rate limit.
            if stl > stl_prev + max_stl_step:
                stl = stl_prev + max_stl_step
            elif stl < stl_prev - max_stl_step:
                stl = stl_prev - max_stl_step
            # The rack stops at full lock: a driver who asks for more gets no more travel
            # (the wheels are clamped there anyway; the STL sensor must agree with them).
            if stl > lock_stl:
                stl = lock_stl
            elif stl < -lock_stl:
                stl = -lock_stl
        else:
            if k > 0 and use_driver[k - 1]:
                # Driver hands over to an open-loop program: blend out the difference
                # linearly instead of jumping the steering.
                handover = stl_prev - stl_open[k]
                handover_left = _HANDOVER_STEPS
            stl = stl_open[k]
            if handover_left > 0:
                stl += handover * handover_left / _HANDOVER_STEPS
                handover_left -= 1
        stl_rate = (stl - stl_prev) / dt if k > 0 else 0.0
        stl_prev = stl
        # Roll steer from the roll at the step's start, held over the step like the
        # steering itself (a 2.5-ms lag on a ~1-Hz roll mode).
        delta_mean = dyn.road_wheel_angles(stl, p, steer, x[dyn.S_PHI])
        dyn.wheel_torques(torque[k], p, wheel_torque)
        dyn.rhs(x, p, tc, steer, wheel_torque, mu, bank_sin[k], k1, aux)

        row = out[k - k_start]
        row[O_U], row[O_V] = dyn.cg_velocity(x, p)
        row[O_R] = x[dyn.S_R]
        row[O_AX] = aux[dyn.A_AX]
        row[O_AY] = aux[dyn.A_AY]
        row[O_STL] = stl
        row[O_STL_RATE] = stl_rate
        row[O_X] = x[dyn.S_X]
        row[O_Y] = x[dyn.S_Y]
        row[O_PSI] = x[dyn.S_PSI]
        row[O_PHI] = x[dyn.S_PHI]
        row[O_THETA] = x[dyn.S_THETA]
        row[O_DELTA] = delta_mean
        for i in range(4):
            row[O_FZ + i] = aux[dyn.A_FZ + i]
            row[O_OMEGA + i] = x[dyn.S_OMEGA + i]
        row[O_GX] = aux[dyn.A_GX]
        row[O_GY] = aux[dyn.A_GY]
        for j in range(N_OUT):
            if not math.isfinite(row[j]):
                return k
        dyn.rk4_step(x, dt, p, tc, steer, wheel_torque, mu, bank_sin[k], k1, work)
        carry[0] = path_index
        carry[1] = stl_prev
        carry[2] = handover
        carry[3] = handover_left
    return -1


@dataclass(frozen=True)
class PreparedVehicle:
    """Everything the compiled loop needs for one vehicle (with payload applied).

    tire is the vehicle's tyre file as parsed; tire_coef holds the front and rear
    axles' scaled coefficients as rows 0 and 1 (see axle_tires).
    """

    vehicle: VehicleParams
    tire: TireParams
    tire_coef: np.ndarray
    params: np.ndarray
    single_track: SingleTrack


def prepare(vehicle: VehicleParams, payload_kg: float = 0.0) -> PreparedVehicle:
    loaded = with_payload(vehicle, payload_kg)
    tire = load_tire(str(loaded.tire_path()))
    front, rear = axle_tires(loaded, tire)
    coef = np.ascontiguousarray(np.stack([front.coefficients(), rear.coefficients()]))
    params = dyn.pack_params(loaded, tire, axle_tires_differ=front.values != rear.values)
    return PreparedVehicle(loaded, tire, coef, params, SingleTrack.from_vehicle(loaded, tire))


def simulate(
    vehicle: VehicleParams,
    maneuver: Maneuver,
    *,
    dt_s: float = DT_S,
    driver: DriverParams | None = None,
) -> SimResult:
    """Simulate one manoeuvre and return its exact signals."""
    stepper = Stepper(vehicle, maneuver, dt_s=dt_s, driver=driver)
    n = len(stepper)
    cols = stepper.advance(n).T.copy()  # one copy: each channel becomes contiguous
    return SimResult(
        maneuver=maneuver,
        vehicle_name=vehicle.name,
        t_s=np.arange(n) * dt_s,
        u_mps=cols[O_U],
        v_mps=cols[O_V],
        yaw_rate_radps=cols[O_R],
        ax_mps2=cols[O_AX],
        ay_mps2=cols[O_AY],
        stl_m=cols[O_STL],
        stl_rate_mps=cols[O_STL_RATE],
        x_m=cols[O_X],
        y_m=cols[O_Y],
        psi_rad=cols[O_PSI],
        roll_rad=cols[O_PHI],
        pitch_rad=cols[O_THETA],
        delta_rad=cols[O_DELTA],
        fz_n=cols[O_FZ : O_FZ + 4].T,
        omega_radps=cols[O_OMEGA : O_OMEGA + 4].T,
        gravity_x_mps2=cols[O_GX],
        gravity_y_mps2=cols[O_GY],
    )


class Stepper:
    """One manoeuvre run advanced through the compiled loop in chunks of samples.

    `simulate` advances it over the whole run at once; the sim node calls `step()` once
    per 2.5-ms sample. Both go through the same compiled code, so they produce
    identical samples.
    """

    def __init__(
        self,
        vehicle: VehicleParams,
        maneuver: Maneuver,
        *,
        dt_s: float = DT_S,
        driver: DriverParams | None = None,
    ) -> None:
        prepared = prepare(vehicle, maneuver.payload_kg)
        self.maneuver = maneuver
        self.vehicle_name = vehicle.name
        self.dt_s = dt_s
        self._prepared = prepared
        self._program = build_program(maneuver, prepared.vehicle, prepared.single_track, dt_s)
        # The linear model (and so the driver's understeer feed-forward) is the dry-road
        # one: cornering stiffness does not depend on μ, and a human driver's habit does
        # not change with it either (it is why low-μ runs saturate the tyres).
        understeer = prepared.single_track.understeer_gradient_rad_per_mps2
        self._driver_cfg = (driver or DriverParams()).as_array(understeer)
        self._x = dyn.initial_state(maneuver.speed_mps, prepared.vehicle.tire_rolling_radius_m)
        n = self._program.stl_open_m.shape[0]
        self._carry = np.array([0.0, self._program.stl_open_m[0] if n else 0.0, 0.0, 0.0])
        self._row = np.empty((1, N_OUT))
        self.k = 0

    def __len__(self) -> int:
        return int(self._program.stl_open_m.shape[0])

    @property
    def done(self) -> bool:
        return self.k >= len(self)

    def advance(self, count: int, out: np.ndarray | None = None) -> np.ndarray:
        """Advance `count` samples; returns their output rows (O_* channel indices)."""
        if self.k + count > len(self):
            raise StopIteration(f"{self.maneuver.name}: only {len(self) - self.k} samples left")
        rows = np.empty((count, N_OUT)) if out is None else out
        p = self._program
        bad = _run(
            self._x,
            self._carry,
            self.k,
            self.k + count,
            self._prepared.params,
            self._prepared.tire_coef,
            self.dt_s,
            p.stl_open_m,
            p.use_driver,
            p.torque_nm,
            float(self.maneuver.mu),
            p.bank_sin,
            p.path_x_m,
            p.path_y_m,
            self._driver_cfg,
            rows,
        )
        if bad >= 0:
            raise SimulationError(
                f"{self.maneuver.name}: non-finite state at t = {bad * self.dt_s:.4f} s "
                f"on {self.vehicle_name}"
            )
        self.k += count
        return rows

    def step(self) -> np.ndarray:
        """Advance one sample; returns its output row (a view, overwritten next call)."""
        return self.advance(1, self._row)[0]
