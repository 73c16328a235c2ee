"""Linear single-track (bicycle) model observer: a Kalman filter on (v_y, ψ̇).

Uses only what a production car measures (X_v, Y_a, ψ̇, STL; not Y_v), so it is the
model-based baseline for the ``measurable`` feature set. States and model (REP-103,
δ = STL / steering ratio, u = X_v):

    v̇_y = −(C_f + C_r)/(m u)·v_y + (−(a C_f − b C_r)/(m u) − u)·ψ̇ + C_f/m·δ
    ψ̈   = −(a C_f − b C_r)/(I_z u)·v_y − (a² C_f + b² C_r)/(I_z u)·ψ̇ + a C_f/I_z·δ

measured through ψ̇ and a_y = v̇_y + u ψ̇. β̂ = atan2(v_y, u). The model is linear in
the tyres, so it is good while |a_y| stays well below μg and biased near the limit:
that is the point of comparing it with a learned model.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.features import channel_indices
from sideslip_msgs_py.parameter_spec import ParameterSpec

from .base import BackendError, Estimate, parameter_values, positive_values
from .params_file import check_keys, read_params_file

X_V, Y_A, YAW_RATE, STL = channel_indices(("x_v_mps", "y_a_mps2", "yaw_rate_radps", "stl_m"))

SHIPPED_DIR = "data/single_track"


@dataclass(frozen=True)
class SingleTrackParams:
    """Bicycle-model parameters (``python -m sideslip_sim.single_track`` writes them)."""

    name: str
    mass_kg: float
    yaw_inertia_kgm2: float
    cg_to_front_axle_m: float
    cg_to_rear_axle_m: float
    cornering_stiffness_front_n_per_rad: float
    cornering_stiffness_rear_n_per_rad: float
    stl_per_road_wheel_angle_m_per_rad: float

    @classmethod
    def load(cls, source: str) -> SingleTrackParams:
        """From a YAML path, or the name of a shipped file (``paper_sedan``, ...)."""
        data, where = read_params_file("single_track", source, SHIPPED_DIR)
        return cls.from_mapping(data, where)

    @classmethod
    def from_mapping(cls, data: object, where: str) -> SingleTrackParams:
        names = [f.name for f in fields(cls)]
        data = check_keys(data, where, names, "single-track parameters")
        values: dict[str, object] = {"name": str(data["name"])}
        for n in names[1:]:
            v = data[n]
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v < math.inf:
                raise BackendError(f"{where}: {n} must be a positive finite number, got {v!r}")
            values[n] = float(v)
        return cls(**values)  # type: ignore[arg-type]


class SingleTrackBackend:
    """Kalman filter on the linear bicycle model (see the module docstring)."""

    name = "single_track"
    sample_period_s = None  # any rate: works on the stamps
    channels = ("x_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m")
    caveats: tuple[str, ...] = ()
    parameters = (
        ParameterSpec(
            "params_file",
            "paper_sedan",
            "Single-track parameters: a shipped name (paper_sedan, compact_rwd) or a YAML "
            "path written by `python -m sideslip_sim.single_track VEHICLE`.",
        ),
        ParameterSpec(
            "yaw_rate_sigma_radps",
            math.radians(0.2),
            "Measurement 1-σ of the yaw rate [rad/s] (default: the paper's 0.2 deg/s).",
        ),
        ParameterSpec(
            "lateral_acceleration_sigma_mps2",
            0.5,
            "Measurement 1-σ of a_y [m/s²]: sensor noise plus the linear model's error.",
        ),
        ParameterSpec(
            "process_sigma_lateral_mps2",
            1.0,
            "Process noise on v̇_y [m/s² per √Hz]: how far the tyres may leave linearity.",
        ),
        ParameterSpec(
            "process_sigma_yaw_radps2",
            0.5,
            "Process noise on ψ̈ [rad/s² per √Hz].",
        ),
        ParameterSpec(
            "min_speed_mps",
            2.0,
            "Below this X_v [m/s] the model is singular: the filter restarts, no estimate.",
        ),
    )

    def __init__(self, values: Mapping[str, object], window_steps: int) -> None:
        del window_steps  # recursive: it reads the newest row only
        v = parameter_values(self.name, self.parameters, values)
        self.params = SingleTrackParams.load(str(v["params_file"]))
        sig = positive_values(
            self.name,
            v,
            (
                "yaw_rate_sigma_radps",
                "lateral_acceleration_sigma_mps2",
                "process_sigma_lateral_mps2",
                "process_sigma_yaw_radps2",
                "min_speed_mps",
            ),
        )
        self.min_speed = sig["min_speed_mps"]
        self._r = np.diag([sig["yaw_rate_sigma_radps"], sig["lateral_acceleration_sigma_mps2"]])
        self._r = self._r**2
        self._q = np.array([sig["process_sigma_lateral_mps2"], sig["process_sigma_yaw_radps2"]])
        self._q = self._q**2
        self.model_id = f"single_track({self.params.name})"
        self.reset()

    def reset(self) -> None:
        self._x: npt.NDArray[np.float64] | None = None
        self._p = np.diag([1.0, 0.1])
        self._last_stamp: int | None = None

    def update(
        self, rows: npt.NDArray[np.float64], stamps_ns: npt.NDArray[np.int64]
    ) -> Estimate | None:
        row = rows[-1]
        stamp = int(stamps_ns[-1])
        u = float(row[X_V])
        if u < self.min_speed:
            self.reset()
            return None
        y = np.array([row[YAW_RATE], row[Y_A]])
        if self._x is None:
            self._x = np.array([0.0, y[0]])
        else:
            dt = (stamp - self._last_stamp) * 1e-9 if self._last_stamp is not None else 0.0
            self._predict(u, float(row[STL]), dt)
        self._last_stamp = stamp
        self._correct(u, float(row[STL]), y)
        v_y = float(self._x[0])
        return Estimate(math.atan2(v_y, u), float(self._p[0, 0]) / (u * u))

    def _matrices(self, u: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        p = self.params
        m, iz = p.mass_kg, p.yaw_inertia_kgm2
        a, b = p.cg_to_front_axle_m, p.cg_to_rear_axle_m
        cf, cr = p.cornering_stiffness_front_n_per_rad, p.cornering_stiffness_rear_n_per_rad
        a_cont = np.array(
            [
                [-(cf + cr) / (m * u), -(a * cf - b * cr) / (m * u) - u],
                [-(a * cf - b * cr) / (iz * u), -(a * a * cf + b * b * cr) / (iz * u)],
            ]
        )
        b_cont = np.array([cf / m, a * cf / iz])
        c = np.array([[0.0, 1.0], [a_cont[0, 0], a_cont[0, 1] + u]])
        d = np.array([0.0, cf / m])
        return a_cont, b_cont, c, d

    def _predict(self, u: float, stl: float, dt: float) -> None:
        if dt <= 0.0:
            return
        delta = stl / self.params.stl_per_road_wheel_angle_m_per_rad
        a_cont, b_cont, _, _ = self._matrices(u)
        ad = a_cont * dt
        # Second-order series of expm(A dt): eigenvalues are tens of 1/s at most, so
        # at 2.5 ms the truncation error is below 1e-4.
        phi = np.eye(2) + ad + 0.5 * ad @ ad
        gamma = (np.eye(2) * dt + 0.5 * ad * dt) @ b_cont
        assert self._x is not None
        self._x = phi @ self._x + gamma * delta
        self._p = phi @ self._p @ phi.T + np.diag(self._q * dt)

    def _correct(self, u: float, stl: float, y: npt.NDArray[np.float64]) -> None:
        delta = stl / self.params.stl_per_road_wheel_angle_m_per_rad
        _, _, c, d = self._matrices(u)
        assert self._x is not None
        innovation = y - (c @ self._x + d * delta)
        s = c @ self._p @ c.T + self._r
        k = self._p @ c.T @ np.linalg.inv(s)
        self._x = self._x + k @ innovation
        # Joseph form keeps P symmetric positive definite over millions of steps.
        ikc = np.eye(2) - k @ c
        self._p = ikc @ self._p @ ikc.T + k @ self._r @ k.T
