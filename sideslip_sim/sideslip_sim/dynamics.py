"""14-DOF full-vehicle model: state layout, parameter packing, right-hand side, RK4.

Degrees of freedom (14): sprung body longitudinal, lateral, vertical (heave), roll,
pitch and yaw; four unsprung masses moving vertically; four wheels spinning. Beside
them the state holds the world pose (X, Y, ψ) for path following and eight tyre
relaxation states (the transient lateral and longitudinal slips of each tyre).

Frames and signs (REP-103): the *vehicle frame* is horizontal, yaw-aligned, at the
whole-vehicle CG; x forward, y left, z up. u, v are the velocity of the CG in that frame
and β = atan2(v, u). Roll φ > 0 lifts the left side (the body leans right, as in a left
turn); pitch θ > 0 is nose-down (as under braking). Vertical displacements z, ζ are
deviations from the static equilibrium on level ground, so gravity and the static
spring preloads cancel and do not appear.

Modelling choices (why):
- Roll and pitch are small angles about a roll axis through the front/rear roll centres
  and about the sprung CG; lateral load transfer therefore emerges in two parts, the
  elastic part through springs/anti-roll bars (dynamic, from the roll DOF) and the
  geometric part through the links at roll-centre height (instantaneous), as in the
  classic 14-DOF formulations. Anti-dive/anti-squat geometry is not modelled.
- Tyre slips are relaxed (Pacejka's first-order contact model), written in deflection
  form so no velocity appears in a denominator: σ·d(tan α)/dt + |V_cx|·tan α = −V_cy.
  That keeps standstill and 10 km/h cornering finite and stiff-free at 2.5 ms.
- IMU accelerations are those of the CG in the vehicle (horizontal) frame, i.e. a
  roll/pitch-compensated IMU: a_x = u̇ − v·r, a_y = v̇ + u·r.
- A banked road (``bank_sin`` = sin γ of a plane falling to the right of ψ = 0) adds
  gravity's in-plane share g_x = −g·sin γ·sin ψ, g_y = −g·sin γ·cos ψ to the vehicle
  frame's accelerations. The tyres and the suspension feel the specific force a − g
  (what an accelerometer tilted with the road reads): the body leans downhill, the
  tyres hold the car against the slope. The normal load stays m·g (cos γ ≥ 0.995 up to
  the manoeuvres' 10 %), and the frame's velocities are those in the road plane.

Corner order everywhere: 0 front-left, 1 front-right, 2 rear-left, 3 rear-right.

Why this module runs past ~400 lines: the state layout, the right-hand side and the RK4
step read the same index constants and are compiled together by numba; the 14-DOF
right-hand side is one function on purpose (split, numba would inline it back and a
reader would lose the equations' order).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sideslip_sim.tire import TireParams
from sideslip_sim.tire_forces import (
    combined_forces4,
    relaxation_lengths,
    rolling_resistance_coefficient,
)
from sideslip_sim.vehicle import GRAVITY_MPS2, VehicleParams

# ---- state layout (index, symbol, unit) ---------------------------------------------
S_X = 0  # X, world position [m]
S_Y = 1  # Y, world position [m]
S_PSI = 2  # ψ, yaw angle [rad]
S_U = 3  # u, longitudinal velocity of the CG in the vehicle frame [m/s]
S_V = 4  # v, lateral velocity of the CG in the vehicle frame [m/s]
S_R = 5  # r = ψ̇, yaw rate [rad/s]
S_Z = 6  # z, sprung-mass heave deviation [m] (up)
S_PHI = 7  # φ, roll angle [rad]
S_THETA = 8  # θ, pitch angle [rad] (nose down > 0)
S_W = 9  # ż [m/s]
S_P = 10  # φ̇ [rad/s]
S_Q = 11  # θ̇ [rad/s]
S_ZU = 12  # ζ_i, unsprung vertical deviation, 4 corners [m]
S_ZUD = 16  # ζ̇_i [m/s]
S_OMEGA = 20  # ω_i, wheel spin rate, 4 corners [rad/s]
S_TANA = 24  # tan α_i, relaxed lateral slip, 4 corners [-]
S_KAPPA = 28  # κ_i, relaxed longitudinal slip, 4 corners [-]
N_STATE = 32

STATE_NAMES: tuple[str, ...] = (
    "x_m", "y_m", "psi_rad", "u_mps", "v_mps", "r_radps",
    "z_m", "phi_rad", "theta_rad", "zdot_mps", "phidot_radps", "thetadot_radps",
    *(f"zeta_{c}_m" for c in ("fl", "fr", "rl", "rr")),
    *(f"zetadot_{c}_mps" for c in ("fl", "fr", "rl", "rr")),
    *(f"omega_{c}_radps" for c in ("fl", "fr", "rl", "rr")),
    *(f"tan_alpha_{c}" for c in ("fl", "fr", "rl", "rr")),
    *(f"kappa_{c}" for c in ("fl", "fr", "rl", "rr")),
)  # fmt: skip

# ---- auxiliary outputs of one right-hand-side evaluation ------------------------------
A_AX = 0  # a_x of the CG in the vehicle frame [m/s^2]
A_AY = 1  # a_y [m/s^2]
A_FZ = 2  # tyre vertical loads, 4 corners [N]
A_FXW = 6  # tyre longitudinal forces in the wheel frame, 4 corners [N]
A_FYW = 10  # tyre lateral forces in the wheel frame, 4 corners [N]
A_DELTA = 14  # road-wheel steer angles, 4 corners [rad]
A_GX = 18  # gravity's share in the road plane, vehicle frame [m/s^2] (0 on a level road)
A_GY = 19
N_AUX = 20

# ---- packed parameters ----------------------------------------------------------------
P_M = 0  # total mass [kg]
P_MS = 1  # sprung mass [kg]
P_MU_F = 2  # unsprung mass per front corner [kg]
P_MU_R = 3
P_A = 4  # CG to front axle [m]
P_B = 5  # CG to rear axle [m]
P_HS = 6  # sprung CG height [m]
P_XS = 7  # sprung CG x relative to whole CG [m]
P_TF = 8  # track widths [m]
P_TR = 9
P_HRA = 10  # roll-axis height below the sprung CG [m]
P_HRC_F = 11  # roll-centre heights [m]
P_HRC_R = 12
P_IXX = 13  # sprung roll inertia about its CG [kg m^2]
P_IYY = 14
P_IZZ = 15  # whole-vehicle yaw inertia [kg m^2]
P_KS_F = 16  # wheel rates [N/m]
P_KS_R = 17
P_CS_F = 18  # damper rates [N s/m]
P_CS_R = 19
P_KARB_F = 20  # anti-roll stiffness [N m/rad]
P_KARB_R = 21
P_IW_F = 22  # wheel spin inertia [kg m^2]
P_IW_R = 23
P_RW = 24  # rolling radius [m]
P_KT = 25  # tyre vertical stiffness [N/m]
P_CT = 26  # tyre vertical damping [N s/m]
P_FZ0_F = 27  # static tyre load per corner [N]
P_FZ0_R = 28
P_HALF_RHO_CDA = 29  # 0.5 ρ C_d A [kg/m]
P_FRONT_DRIVE = 30  # fraction of wheel torque to the front axle [-]
P_STL_RATIO = 31  # STL per mean road-wheel angle [m/rad]
P_ACKERMANN = 32  # Ackermann fraction [-]
P_MAX_DELTA = 33  # steering lock [rad]
P_FRR = 34  # rolling-resistance coefficient [-]
P_ROLL_STEER_F = 35  # road-wheel angle per roll angle, > 0 roll understeer [rad/rad]
P_ROLL_STEER_R = 36
P_AXLE_TIRES = 37  # 1 when the axles' tyre coefficients differ (tc rows 0 and 1), else 0
N_PARAM = 38

# Slip-velocity floor in the relaxation equations [m/s]: a standing tyre still relaxes
# (decays) its deflection instead of acting as an undamped spring; a floor (not an
# offset) leaves the steady-state slip exact above 0.1 m/s.
_V_RELAX_FLOOR = 0.1
# Wheel speed over which rolling resistance fades in [rad/s] (smooth sign at standstill).
_OMEGA_RR_SCALE = 1.0


def pack_params(vehicle: VehicleParams, tire: TireParams, axle_tires_differ: bool) -> np.ndarray:
    """Pack a vehicle (and the tyre's vertical/rolling properties) for the compiled model.

    axle_tires_differ: the front and rear rows of the tyre-coefficient array differ (the
    model then evaluates the force kernel once per axle instead of once per car).
    """
    p = np.zeros(N_PARAM)
    L = vehicle.wheelbase_m
    p[P_M] = vehicle.mass_kg
    p[P_MS] = vehicle.sprung_mass_kg
    p[P_MU_F] = vehicle.unsprung_mass_front_kg
    p[P_MU_R] = vehicle.unsprung_mass_rear_kg
    p[P_A] = vehicle.cg_to_front_axle_m
    p[P_B] = vehicle.cg_to_rear_axle_m
    p[P_HS] = vehicle.sprung_cg_height_m
    p[P_XS] = vehicle.sprung_cg_x_m
    p[P_TF] = vehicle.track_front_m
    p[P_TR] = vehicle.track_rear_m
    h_f, h_r = vehicle.roll_center_height_front_m, vehicle.roll_center_height_rear_m
    roll_axis_height = h_r + (h_f - h_r) * (vehicle.sprung_cg_x_m + vehicle.cg_to_rear_axle_m) / L
    p[P_HRA] = vehicle.sprung_cg_height_m - roll_axis_height
    p[P_HRC_F] = h_f
    p[P_HRC_R] = h_r
    p[P_IXX] = vehicle.roll_inertia_kgm2
    p[P_IYY] = vehicle.pitch_inertia_kgm2
    p[P_IZZ] = vehicle.yaw_inertia_kgm2
    p[P_KS_F] = vehicle.spring_front_n_per_m
    p[P_KS_R] = vehicle.spring_rear_n_per_m
    p[P_CS_F] = vehicle.damper_front_ns_per_m
    p[P_CS_R] = vehicle.damper_rear_ns_per_m
    p[P_KARB_F] = vehicle.antiroll_front_nm_per_rad
    p[P_KARB_R] = vehicle.antiroll_rear_nm_per_rad
    p[P_IW_F] = vehicle.wheel_spin_inertia_front_kgm2
    p[P_IW_R] = vehicle.wheel_spin_inertia_rear_kgm2
    p[P_RW] = vehicle.tire_rolling_radius_m
    p[P_KT] = tire.vertical_stiffness_n_per_m
    p[P_CT] = tire.vertical_damping_ns_per_m
    p[P_FZ0_F] = 0.5 * vehicle.static_axle_load_front_n
    p[P_FZ0_R] = 0.5 * vehicle.static_axle_load_rear_n
    p[P_HALF_RHO_CDA] = (
        0.5 * vehicle.air_density_kg_per_m3 * vehicle.drag_coefficient * vehicle.frontal_area_m2
    )
    p[P_FRONT_DRIVE] = vehicle.front_drive_fraction
    p[P_STL_RATIO] = vehicle.stl_per_road_wheel_angle_m_per_rad
    p[P_ACKERMANN] = vehicle.ackermann_fraction
    p[P_MAX_DELTA] = vehicle.max_road_wheel_angle_rad
    p[P_FRR] = rolling_resistance_coefficient(tire.coefficients())
    p[P_ROLL_STEER_F] = vehicle.roll_steer_front_rad_per_rad
    p[P_ROLL_STEER_R] = vehicle.roll_steer_rear_rad_per_rad
    p[P_AXLE_TIRES] = 1.0 if axle_tires_differ else 0.0
    return p


N_STEER = 12  # steer array: angles δ_i, then cos δ_i, then sin δ_i (held over a step)


@njit(cache=True, error_model="numpy")
def road_wheel_angles(stl_m: float, p: np.ndarray, out: np.ndarray, roll_rad: float = 0.0) -> float:
    """Road-wheel angles from STL into out (N_STEER: δ_i, cos δ_i, sin δ_i); returns δ.

    Roll steer adds −ε_f·φ to both front wheels and +ε_r·φ to both rear wheels (φ > 0
    in a left turn, so ε > 0 steers the front out of the turn and the rear into it:
    roll understeer). The returned mean δ is the steering's alone, without roll steer.

    δ = STL / ratio, clamped to the lock. With full Ackermann the inner wheel steers more,
    so that both front axles point at one turn centre on the rear-axle line:
    tan δ_in = L tan δ / (L − t/2 tan δ). The Ackermann fraction blends with parallel
    steer. Mirror-symmetric: δ_L(−s) = −δ_R(s).
    """
    delta = stl_m / p[P_STL_RATIO]
    lock = p[P_MAX_DELTA]
    if delta > lock:
        delta = lock
    elif delta < -lock:
        delta = -lock
    wheelbase = p[P_A] + p[P_B]
    t = math.tan(delta)
    half_track = 0.5 * p[P_TF]
    # Left wheel: inner in a left turn (t > 0); denominators stay > 0 below 60° lock.
    d_left = math.atan(wheelbase * t / (wheelbase - half_track * t))
    d_right = math.atan(wheelbase * t / (wheelbase + half_track * t))
    ack = p[P_ACKERMANN]
    front_roll = -p[P_ROLL_STEER_F] * roll_rad
    rear_roll = p[P_ROLL_STEER_R] * roll_rad
    out[0] = ack * d_left + (1.0 - ack) * delta + front_roll
    out[1] = ack * d_right + (1.0 - ack) * delta + front_roll
    out[2] = rear_roll
    out[3] = rear_roll
    for i in range(4):
        out[4 + i] = math.cos(out[i])
        out[8 + i] = math.sin(out[i])
    return delta


@njit(cache=True, error_model="numpy")
def rhs(
    x: np.ndarray,
    p: np.ndarray,
    tc: np.ndarray,
    steer: np.ndarray,
    wheel_torque: np.ndarray,
    mu: float,
    bank_sin: float,
    dx: np.ndarray,
    aux: np.ndarray,
) -> None:
    """Time derivative dx of the state x for held inputs.

    tc: tyre coefficients, shape (2, n): row 0 the front axle's, row 1 the rear's;
    steer: road-wheel angles per corner with their cosines and sines (see
    road_wheel_angles); aux doubles as scratch for the per-corner forces;
    wheel_torque: drive torque per wheel [N m];
    mu: road friction relative to the tyre's test surface [-]; bank_sin: the road's
    sin γ, > 0 falling to the right of ψ = 0 (module docstring). Fills dx and aux.
    """
    u = x[S_U]
    v = x[S_V]
    r = x[S_R]
    phi = x[S_PHI]
    theta = x[S_THETA]
    a = p[P_A]
    b = p[P_B]
    xs = p[P_XS]
    tf2 = 0.5 * p[P_TF]
    tr2 = 0.5 * p[P_TR]
    rw = p[P_RW]

    sum_fx = 0.0
    sum_fy = 0.0
    yaw_moment = 0.0
    roll_moment = 0.0
    pitch_moment = 0.0
    heave_force = 0.0
    fy_front = 0.0
    fy_rear = 0.0

    # Suspension compressions (> 0 when wheel and body approach), per corner. The aux
    # slots for forces double as scratch until they are filled (no heap allocation in
    # the innermost function).
    comp = aux[A_FXW : A_FXW + 4]
    comp_rate = aux[A_FYW : A_FYW + 4]
    for i in range(4):
        front = i < 2
        cx = a if front else -b
        cy = (tf2 if front else tr2) * (1.0 if i % 2 == 0 else -1.0)
        body_dz = x[S_Z] + cy * phi - (cx - xs) * theta
        body_dz_rate = x[S_W] + cy * x[S_P] - (cx - xs) * x[S_Q]
        comp[i] = x[S_ZU + i] - body_dz
        comp_rate[i] = x[S_ZUD + i] - body_dz_rate

    body_force = dx[S_ZUD : S_ZUD + 4]  # overwritten with accelerations at the end
    arb_f = p[P_KARB_F] / (p[P_TF] * p[P_TF]) * (comp[0] - comp[1])
    arb_r = p[P_KARB_R] / (p[P_TR] * p[P_TR]) * (comp[2] - comp[3])
    body_force[0] = p[P_KS_F] * comp[0] + p[P_CS_F] * comp_rate[0] + arb_f
    body_force[1] = p[P_KS_F] * comp[1] + p[P_CS_F] * comp_rate[1] - arb_f
    body_force[2] = p[P_KS_R] * comp[2] + p[P_CS_R] * comp_rate[2] + arb_r
    body_force[3] = p[P_KS_R] * comp[3] + p[P_CS_R] * comp_rate[3] - arb_r

    # Loads and slip dynamics per corner; the four tyres' forces then come from one
    # SIMD-vectorised call (the tyres are ~3/4 of the cost of a step).
    fz = aux[A_FZ : A_FZ + 4]
    for i in range(4):
        front = i < 2
        cx = a if front else -b
        cy = (tf2 if front else tr2) * (1.0 if i % 2 == 0 else -1.0)
        fz0 = p[P_FZ0_F] if front else p[P_FZ0_R]
        fz_i = fz0 - p[P_KT] * x[S_ZU + i] - p[P_CT] * x[S_ZUD + i]
        if fz_i < 0.0:
            fz_i = 0.0  # wheel lifted: the tyre cannot pull the wheel down
        fz[i] = fz_i

        # Contact-patch velocity in the vehicle frame, then in the wheel frame.
        vx = u - r * cy
        vy = v + r * cx
        cd = steer[4 + i]
        sd = steer[8 + i]
        vcx = vx * cd + vy * sd
        vcy = -vx * sd + vy * cd

        sigma_kappa, sigma_alpha = relaxation_lengths(tc[0] if front else tc[1], fz_i)
        speed = max(abs(vcx), _V_RELAX_FLOOR)
        dx[S_TANA + i] = (-vcy - speed * x[S_TANA + i]) / sigma_alpha
        dx[S_KAPPA + i] = (x[S_OMEGA + i] * rw - vcx - speed * x[S_KAPPA + i]) / sigma_kappa

    fxw_all = aux[A_FXW : A_FXW + 4]
    fyw_all = aux[A_FYW : A_FYW + 4]
    kappa = x[S_KAPPA : S_KAPPA + 4]
    tan_alpha = x[S_TANA : S_TANA + 4]
    if p[P_AXLE_TIRES] != 0.0:
        # Other tyres on each axle: the rear tyre's forces first, kept for corners 2-3,
        # then the front tyre's for corners 0-1 (two kernel calls instead of one).
        combined_forces4(tc[1], fz, kappa, tan_alpha, mu, fxw_all, fyw_all)
        fx_rl, fx_rr, fy_rl, fy_rr = fxw_all[2], fxw_all[3], fyw_all[2], fyw_all[3]
        combined_forces4(tc[0], fz, kappa, tan_alpha, mu, fxw_all, fyw_all)
        fxw_all[2], fxw_all[3], fyw_all[2], fyw_all[3] = fx_rl, fx_rr, fy_rl, fy_rr
    else:
        combined_forces4(tc[0], fz, kappa, tan_alpha, mu, fxw_all, fyw_all)

    for i in range(4):
        front = i < 2
        cx = a if front else -b
        cy = (tf2 if front else tr2) * (1.0 if i % 2 == 0 else -1.0)
        fxw = fxw_all[i]
        fyw = fyw_all[i]
        cd = steer[4 + i]
        sd = steer[8 + i]
        omega = x[S_OMEGA + i]
        inertia = p[P_IW_F] if front else p[P_IW_R]
        # Smooth sign of ω; tanh(x) rounds to ±1.0 in double precision for |x| > 19.1,
        # so the (costly) call is only made near standstill.
        spin = omega / _OMEGA_RR_SCALE
        smooth_sign = math.tanh(spin) if abs(spin) < 20.0 else (1.0 if spin > 0.0 else -1.0)
        rolling = p[P_FRR] * fz[i] * rw * smooth_sign
        dx[S_OMEGA + i] = (wheel_torque[i] - rw * fxw - rolling) / inertia

        fx_i = fxw * cd - fyw * sd
        fy_i = fxw * sd + fyw * cd
        sum_fx += fx_i
        sum_fy += fy_i
        yaw_moment += cx * fy_i - cy * fx_i
        if front:
            fy_front += fy_i
        else:
            fy_rear += fy_i
        roll_moment += cy * body_force[i]
        pitch_moment -= (cx - xs) * body_force[i]
        heave_force += body_force[i]
        aux[A_DELTA + i] = steer[i]

    sum_fx -= p[P_HALF_RHO_CDA] * u * abs(u)

    m = p[P_M]
    ms = p[P_MS]
    g = GRAVITY_MPS2
    psi = x[S_PSI]
    cpsi = math.cos(psi)
    spsi = math.sin(psi)
    g_x = -g * bank_sin * spsi
    g_y = -g * bank_sin * cpsi

    # Lateral + roll (coupled through the sprung mass swinging about the roll axis):
    #   m v̇ − ms h' φ̈ = ΣFy − m u r + m g_y
    #   −ms h' v̇ + (Ixx + ms h'^2) φ̈ = ms g h' φ + M_susp + ms h' (u r − g_y)
    h_roll = p[P_HRA]
    a11 = m
    a12 = -ms * h_roll
    a22 = p[P_IXX] + ms * h_roll * h_roll
    rhs1 = sum_fy - m * u * r + m * g_y
    rhs2 = ms * g * h_roll * phi + roll_moment + ms * h_roll * (u * r - g_y)
    det = a11 * a22 - a12 * a12
    v_dot = (rhs1 * a22 - a12 * rhs2) / det
    phi_ddot = (a11 * rhs2 - a12 * rhs1) / det

    # Longitudinal + pitch (pitch centre on the ground, no anti-dive/anti-squat):
    #   m u̇ + ms hs θ̈ = ΣFx + m v r + m g_x
    #   ms hs u̇ + (Iyy + ms hs^2) θ̈ = ms g hs θ + M_susp + ms hs (v r + g_x)
    hs = p[P_HS]
    b11 = m
    b12 = ms * hs
    b22 = p[P_IYY] + ms * hs * hs
    rhs3 = sum_fx + m * v * r + m * g_x
    rhs4 = ms * g * hs * theta + pitch_moment + ms * hs * (v * r + g_x)
    det2 = b11 * b22 - b12 * b12
    u_dot = (rhs3 * b22 - b12 * rhs4) / det2
    theta_ddot = (b11 * rhs4 - b12 * rhs3) / det2

    dx[S_X] = u * cpsi - v * spsi
    dx[S_Y] = u * spsi + v * cpsi
    dx[S_PSI] = r
    dx[S_U] = u_dot
    dx[S_V] = v_dot
    dx[S_R] = yaw_moment / p[P_IZZ]
    dx[S_Z] = x[S_W]
    dx[S_PHI] = x[S_P]
    dx[S_THETA] = x[S_Q]
    dx[S_W] = heave_force / ms
    dx[S_P] = phi_ddot
    dx[S_Q] = theta_ddot

    # Unsprung masses: tyre force up, suspension force down, and the load transfer that
    # bypasses the springs: the links carry the sprung share of each axle's lateral
    # force at roll-centre height (geometric transfer); the unsprung masses' own
    # inertia acts at wheel-centre height, laterally per axle and longitudinally
    # between the axles. The unsprung masses do not roll, so their acceleration is
    # that of the chassis reference point. What loads them is the specific force: on a
    # banked road gravity's share pulls the unsprung masses as it pulls the body.
    ay_ref = v_dot + u * r - g_y
    ax_ref = u_dot - v * r - g_x
    m_u_f = 2.0 * p[P_MU_F]
    m_u_r = 2.0 * p[P_MU_R]
    geo_f = ((fy_front - m_u_f * ay_ref) * p[P_HRC_F] + m_u_f * ay_ref * rw) / p[P_TF]
    geo_r = ((fy_rear - m_u_r * ay_ref) * p[P_HRC_R] + m_u_r * ay_ref * rw) / p[P_TR]
    pitch_unsprung = (m_u_f + m_u_r) * ax_ref * rw / (2.0 * (a + b))  # per wheel
    for i in range(4):
        front = i < 2
        fz0 = p[P_FZ0_F] if front else p[P_FZ0_R]
        mu_i = p[P_MU_F] if front else p[P_MU_R]
        geo = geo_f if front else geo_r
        push_down = -geo if i % 2 == 0 else geo  # outer (right in a left turn) loads up
        push_down += -pitch_unsprung if front else pitch_unsprung  # rear loads up under drive
        dx[S_ZU + i] = x[S_ZUD + i]
        dx[S_ZUD + i] = (
            (fz[i] - fz0) - body_force[i] - push_down
        ) / mu_i  # reads, then writes slot i

    # Acceleration of the whole-vehicle CG (sprung mass rolling/pitching included).
    aux[A_AX] = sum_fx / m + g_x
    aux[A_AY] = sum_fy / m + g_y
    aux[A_GX] = g_x
    aux[A_GY] = g_y


@njit(cache=True, error_model="numpy")
def cg_velocity(x: np.ndarray, p: np.ndarray) -> tuple[float, float]:
    """(u, v) of the whole-vehicle CG in the vehicle frame [m/s].

    The states u, v belong to the chassis reference point (the static CG position,
    which does not roll or pitch); the sprung mass's CG moves relative to it by
    −h'·φ̇ sideways and +h_s·θ̇ forwards, so the whole CG by (m_s/m) of that.
    """
    share = p[P_MS] / p[P_M]
    return (x[S_U] + share * p[P_HS] * x[S_Q], x[S_V] - share * p[P_HRA] * x[S_P])


@njit(cache=True, error_model="numpy")
def wheel_torques(total_torque: float, p: np.ndarray, out: np.ndarray) -> None:
    """Split the manoeuvre's total wheel torque [N m]: axle by layout, open differential."""
    front = p[P_FRONT_DRIVE] * total_torque
    out[0] = 0.5 * front
    out[1] = 0.5 * front
    out[2] = 0.5 * (total_torque - front)
    out[3] = 0.5 * (total_torque - front)


@njit(cache=True, error_model="numpy")
def rk4_step(
    x: np.ndarray,
    dt: float,
    p: np.ndarray,
    tc: np.ndarray,
    steer: np.ndarray,
    torque: np.ndarray,
    mu: float,
    bank_sin: float,
    k1: np.ndarray,
    work: np.ndarray,
) -> None:
    """Advance x in place by one classic 4th-order Runge-Kutta step of dt seconds.

    k1 must already hold rhs(x): the caller evaluated it to record the sample's own
    accelerations, so it is not computed twice. Inputs are held over the step
    (zero-order hold, as a 400-Hz ECU would). work: scratch of shape (5, N_STATE).
    """
    n = x.shape[0]
    k2 = work[0]
    k3 = work[1]
    k4 = work[2]
    xt = work[3]
    scratch = work[4]  # aux of the inner stages is not needed
    for j in range(n):
        xt[j] = x[j] + 0.5 * dt * k1[j]
    rhs(xt, p, tc, steer, torque, mu, bank_sin, k2, scratch)
    for j in range(n):
        xt[j] = x[j] + 0.5 * dt * k2[j]
    rhs(xt, p, tc, steer, torque, mu, bank_sin, k3, scratch)
    for j in range(n):
        xt[j] = x[j] + dt * k3[j]
    rhs(xt, p, tc, steer, torque, mu, bank_sin, k4, scratch)
    for j in range(n):
        x[j] += dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])


def initial_state(speed_mps: float, rolling_radius_m: float) -> np.ndarray:
    """Static equilibrium, driving straight ahead at speed_mps with wheels rolling freely."""
    x = np.zeros(N_STATE)
    x[S_U] = speed_mps
    x[S_OMEGA : S_OMEGA + 4] = speed_mps / rolling_radius_m
    return x
