"""The physics filters (single-track KF, UKF) replayed over a recorded run through the
estimator core, as the node runs them: the baselines ``sideslip-evaluate`` scores beside
the networks."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .dataset import Run, filtered_span

FloatArray = npt.NDArray[np.float64]


class FilterError(ValueError):
    """A physics filter that cannot be built from the given parameters."""


FILTER_LABELS = {"single_track": "Single-track KF", "ukf": "UKF"}


def physics_filter(run: Run, backend: str, params_file: str, window_steps: int) -> FloatArray:
    """β̂ [rad] of the estimator's ``backend`` (``single_track`` or ``ukf``, with
    ``params_file``) fed the run through the estimator core as the node would, for
    samples[window_steps-1:] (NaN where it gives none). A run cut out of a recording is
    filtered from the recording's start, as the node ran through it."""
    from sideslip_estimator.backends import BackendError, create_backend
    from sideslip_estimator.estimator import Estimator, EstimatorParams
    from sideslip_estimator.replay import replay, replay_columns

    try:
        backend_ = create_backend(backend, {"params_file": params_file}, window_steps)
    except (BackendError, ImportError) as err:
        raise FilterError(f"{FILTER_LABELS[backend]}: {err}") from None
    est = Estimator(backend_, EstimatorParams(window_steps=window_steps))
    span, offset = filtered_span(run)
    return replay(est, replay_columns(span)).beta_rad[offset + window_steps - 1 :]
