"""Kinematic baseline: β̂ = atan2(Y_v, X_v) of the measured body velocity.

Model-free: with the paper's inputs, Y_v/X_v *is* β up to sensor noise, so every
learned model must beat this. Smoothing averages the velocity components over the
last ``smoothing_steps`` samples before the atan2 (averaging the components, not the
angles, keeps it unbiased where X_v is small and noisy). The average lags by
(n − 1)/2 samples; n = 1 is the raw baseline.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.features import channel_indices
from sideslip_msgs_py.parameter_spec import ParameterSpec

from .base import BackendError, Estimate, parameter_values

X_V, Y_V = channel_indices(("x_v_mps", "y_v_mps"))


class KinematicBackend:
    """atan2 of the (optionally averaged) measured velocity."""

    name = "kinematic"
    sample_period_s = None  # any rate: works on the stamps
    channels = ("x_v_mps", "y_v_mps")
    caveats: tuple[str, ...] = ()
    parameters = (
        ParameterSpec(
            "smoothing_steps",
            1,
            "Samples averaged before atan2(Y_v, X_v): 1 = raw, up to window_steps.",
        ),
        ParameterSpec(
            "velocity_sigma_mps",
            1.0 / 3.6,
            "Assumed 1-σ noise of X_v and Y_v [m/s] for the published variance "
            "(default: the paper's 1 km/h).",
        ),
    )

    def __init__(self, values: Mapping[str, object], window_steps: int) -> None:
        v = parameter_values(self.name, self.parameters, values)
        steps, sigma = int(v["smoothing_steps"]), float(v["velocity_sigma_mps"])
        if not 1 <= steps <= window_steps:
            msg = f"kinematic.smoothing_steps must be in 1..{window_steps}, got {steps}"
            raise BackendError(msg)
        if not (math.isfinite(sigma) and sigma >= 0.0):
            msg = f"kinematic.velocity_sigma_mps must be finite and >= 0, got {sigma}"
            raise BackendError(msg)
        self.steps = steps
        self.sigma = sigma
        self.model_id = f"kinematic(smoothing_steps={steps})"

    def reset(self) -> None:
        """Stateless: nothing to forget."""

    def update(
        self, rows: npt.NDArray[np.float64], stamps_ns: npt.NDArray[np.int64]
    ) -> Estimate | None:
        n = min(self.steps, rows.shape[0])
        recent = rows[-n:]
        v_x = float(recent[:, X_V].sum()) / n
        v_y = float(recent[:, Y_V].sum()) / n
        speed2 = v_x * v_x + v_y * v_y
        if speed2 == 0.0:
            return None
        # First-order: an independent σ on each component moves the angle by σ/|v|.
        return Estimate(math.atan2(v_y, v_x), self.sigma * self.sigma / (n * speed2))
