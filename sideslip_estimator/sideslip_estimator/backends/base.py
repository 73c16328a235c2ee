"""What every estimator back-end provides: one Protocol, one result type, its parameters."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.parameters import ParameterSpec


class BackendError(ValueError):
    """A back-end cannot be built from its parameters (message names the parameter/file)."""


@dataclass(frozen=True)
class Estimate:
    """β̂ [rad] (atan2(v_y, v_x) at the CG, > 0 sliding left) and its variance [rad²]."""

    beta_rad: float
    variance_rad2: float


class Backend(Protocol):
    """A sideslip estimator over the sliding window.

    ``update`` is called once per accepted sample with the window so far: rows oldest
    first, columns in :data:`sideslip_msgs_py.features.CHANNELS` order, and their
    stamps [ns]. Recursive back-ends (observers) take the newest row each call;
    window models read all rows. ``None`` means "no estimate for this sample". The
    runtime calls ``reset`` whenever the window restarts (stamp went backwards, long
    gap) and publishes only once the window is full.
    """

    name: str
    model_id: str
    """Identifies the model (and its parameters) in /sideslip/status."""

    def reset(self) -> None: ...

    def update(
        self, rows: npt.NDArray[np.float64], stamps_ns: npt.NDArray[np.int64]
    ) -> Estimate | None: ...


class BackendFactory(Protocol):
    """Builds a back-end from its parameter values (keys = BackendParameter names)."""

    parameters: tuple[ParameterSpec, ...]

    def __call__(self, values: Mapping[str, object], window_steps: int) -> Backend: ...
