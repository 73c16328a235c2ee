"""What every estimator back-end provides: one Protocol, one result type, its parameters."""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.parameter_spec import ParameterSpec


class BackendError(ValueError):
    """A back-end cannot be built from its parameters (message names the parameter/file)."""


@dataclass(frozen=True)
class Estimate:
    """β̂ [rad] (atan2(v_y, v_x) at the CG, > 0 sliding left) and its variance [rad²]."""

    beta_rad: float
    variance_rad2: float
    beyond_fit_range: bool = False
    """The input window reached beyond the driving a fine-tuned model was fitted on
    (:class:`~sideslip_msgs_py.uncertainty.FitRange`): its σ was widened, or its start
    model's estimate and σ are these (``pso_lstm.beyond_fit_range``)."""


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
    sample_period_s: float | None
    """The step [s] the model was trained at, which its inputs must keep; None for
    back-ends that integrate over the stamps and run at any rate."""
    channels: tuple[str, ...]
    """The window channels (``CHANNELS`` names) the back-end reads."""
    caveats: tuple[str, ...]
    """Standing limits of this configuration (e.g. a car outside the model's training
    cars), which the node's status reports as WARN; empty when there are none."""

    def reset(self) -> None: ...

    def update(
        self, rows: npt.NDArray[np.float64], stamps_ns: npt.NDArray[np.int64]
    ) -> Estimate | None: ...


class BackendFactory(Protocol):
    """Builds a back-end from its parameter values (keys = BackendParameter names)."""

    parameters: tuple[ParameterSpec, ...]

    def __call__(self, values: Mapping[str, object], window_steps: int) -> Backend: ...


def parameter_values(
    backend: str, specs: Iterable[ParameterSpec], values: Mapping[str, object]
) -> dict[str, bool | int | float | str]:
    """The spec defaults overlaid with ``values``, each checked against its spec's type.

    Unknown keys are refused (a typo must not fall back to a default silently); an int
    is accepted for a double and a bool for a string that takes one (stored as ``true``
    / ``false``, as the node does); nothing else is converted.
    """
    known = {p.name: p for p in specs}
    unknown = sorted(set(values) - set(known))
    if unknown:
        msg = f"{backend}: unknown parameter(s) {unknown} (known: {', '.join(known)})"
        raise BackendError(msg)
    out: dict[str, bool | int | float | str] = {}
    for name, spec in known.items():
        v = values.get(name, spec.default)
        kind = type(spec.default)
        if spec.takes_bool and isinstance(v, bool):
            ok, v = True, "true" if v else "false"
        elif isinstance(v, bool) != (kind is bool):
            ok = False
        elif kind is float:
            ok = isinstance(v, numbers.Real)
            v = float(v) if ok else v  # type: ignore[arg-type]
        elif kind is int:
            ok = isinstance(v, numbers.Integral)
            v = int(v) if ok else v  # type: ignore[call-overload]
        else:
            ok = isinstance(v, kind)
        if not ok:
            raise BackendError(f"{backend}.{name} must be a {spec.type_name}, got {v!r}")
        out[name] = v  # type: ignore[assignment]
    return out


def positive_values(
    backend: str, values: Mapping[str, object], names: Iterable[str]
) -> dict[str, float]:
    """``values[name]`` as floats for ``names``, each checked finite and > 0 (sigmas,
    time constants, speed thresholds); BackendError names the first that is not."""
    out: dict[str, float] = {}
    for name in names:
        x = float(values[name])  # type: ignore[arg-type]
        if not (math.isfinite(x) and x > 0.0):
            raise BackendError(f"{backend}.{name} must be finite and > 0, got {x!r}")
        out[name] = x
    return out
