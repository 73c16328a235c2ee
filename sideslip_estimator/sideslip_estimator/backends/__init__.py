"""Estimator back-ends: one :class:`~.base.Backend` Protocol and a registry by name.

The node picks one with its ``backend`` parameter; each back-end declares its own
parameters (``<backend>.<name>``). Adding one = a module with a class that has
``name``, ``parameters`` and ``__init__(values, window_steps)``, plus a line here.
"""

from __future__ import annotations

from collections.abc import Mapping

from .base import Backend, BackendError, BackendFactory, Estimate
from .kinematic import KinematicBackend
from .pso_lstm import PsoLstmBackend  # imports torch only when built
from .single_track import SingleTrackBackend, SingleTrackParams
from .ukf import UkfBackend  # imports filterpy only when built
from .ukf_model import UkfParams

BACKENDS: dict[str, BackendFactory] = {
    KinematicBackend.name: KinematicBackend,
    SingleTrackBackend.name: SingleTrackBackend,
    PsoLstmBackend.name: PsoLstmBackend,
    UkfBackend.name: UkfBackend,
}


def backend_factory(name: str) -> BackendFactory:
    try:
        return BACKENDS[name]
    except KeyError:
        msg = f"unknown backend {name!r} (known: {', '.join(BACKENDS)})"
        raise BackendError(msg) from None


def create_backend(name: str, values: Mapping[str, object], window_steps: int) -> Backend:
    """Build the back-end ``name`` from its parameter values."""
    return backend_factory(name)(values, window_steps)


__all__ = [
    "BACKENDS",
    "Backend",
    "BackendError",
    "Estimate",
    "SingleTrackParams",
    "UkfParams",
    "backend_factory",
    "create_backend",
]
