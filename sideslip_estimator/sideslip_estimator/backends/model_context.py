"""What a model reads besides its window: the car, the UKF observer, and whether the car
lies inside the range of cars the model was trained on.

A model that reads the car (``vehicle.*`` inputs, road-wheel angle, ...) takes it from
``pso_lstm.vehicle_file`` (a description YAML, see
:class:`~sideslip_msgs_py.vehicle_description.VehicleDescription`, or a simulator
vehicle file), else from the car stored in the model; without either it is refused at
start-up (:func:`vehicle_for`). A model that reads the UKF observer (``ukf.*`` inputs or
the ``ukf`` prior: a residual on the UKF) runs the ``ukf`` back-end beside its window,
on every sample, with the filter settings stored in the model and the car's ``ukf``
params file (``pso_lstm.observer_params_file``, required for such a model;
:func:`observer_for`); a window in which the filter gave no estimate for some row
(below its speed, after a restart) gives none. Such a model may carry its training
cars' envelope (:mod:`sideslip_msgs_py.fleet_envelope`), checked against the car of
that params file; outside it, ``pso_lstm.outside_fleet`` chooses between the UKF's own
estimate (the default for a residual on the UKF), the model's, or no start, and the
status WARNs (:func:`fleet_check`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING

from sideslip_msgs_py.artifact import ModelMetadata
from sideslip_msgs_py.fleet_envelope import (
    OUTSIDE_FLEET,
    EnvelopeError,
    FleetEnvelope,
    publishes_prior,
)
from sideslip_msgs_py.uncertainty import Uncertainty
from sideslip_msgs_py.vehicle_description import VehicleDescription, VehicleDescriptionError

from .base import BackendError

if TYPE_CHECKING:
    from .ukf import UkfBackend


def vehicle_for(meta: ModelMetadata, vehicle_file: str, label: str) -> VehicleDescription | None:
    """The car a model reads: the vehicle_file, else the model's own; None if not read."""
    if not meta.needs_vehicle:
        return None
    try:
        if vehicle_file:
            return VehicleDescription.load(Path(vehicle_file).expanduser())
        if meta.vehicle is not None:
            return VehicleDescription.from_mapping(meta.vehicle, f"{label}: vehicle")
    except VehicleDescriptionError as err:
        raise BackendError(f"pso_lstm.vehicle_file: {err}") from None
    msg = (
        f"pso_lstm.model_file {label} reads the car's nominal parameters "
        f"({', '.join(meta.features)}); set pso_lstm.vehicle_file:=/path/to/car.yaml"
    )
    raise BackendError(msg)


def observer_for(
    meta: ModelMetadata, params_file: str, label: str, window_steps: int
) -> UkfBackend | None:
    """The ``ukf`` back-end a model reads (its stored settings, the car's params file);
    None for a model that reads no observer."""
    if not meta.needs_observer:
        return None
    if not params_file:
        msg = (
            f"pso_lstm.model_file {label} is anchored on the UKF observer; set "
            "pso_lstm.observer_params_file:=/path/to/car.ukf.yaml (written by `python -m "
            "sideslip_sim.ukf_params VEHICLE`)"
        )
        raise BackendError(msg)
    from .ukf import UkfBackend  # filterpy is imported only for a model that needs it

    assert meta.observer is not None  # ModelMetadata checks it
    try:
        return UkfBackend({**meta.observer, "params_file": params_file}, window_steps)
    except BackendError as err:
        raise BackendError(f"pso_lstm.observer_params_file: {err}") from None


def published_uncertainty(
    meta: ModelMetadata, observer: UkfBackend | None
) -> tuple[Uncertainty | None, bool]:
    """(the σ model to publish, whether it is the one for described car files). A car
    file made from a description guesses the tyres; a model that reads the UKF errs more
    with it, and its σ for such files (``Uncertainty.described``) was calibrated with them."""
    if meta.uncertainty is None:
        return None, False
    unc = Uncertainty.from_dict(meta.uncertainty)
    if observer is None:
        return unc, False
    chosen = unc.for_axles(observer.params.axles_from)
    return chosen, chosen is not unc


def fleet_check(
    meta: ModelMetadata, observer: UkfBackend | None, mode: str, label: str
) -> tuple[tuple[str, ...], bool]:
    """(caveats for the node's status, publish the UKF's estimate instead of the model's).

    A model with an envelope that reads the UKF observer is checked against the car of
    ``observer`` (its params file). Outside the envelope, ``mode`` decides: ``prior``
    publishes the UKF's own β̂ (the network's correction was learnt on other cars),
    ``network`` the model's estimate, ``refuse`` stops the start-up, ``auto`` is
    ``prior`` for a residual on the UKF and ``network`` otherwise (``prior`` on a model
    with a kinematic prior publishes that prior). Both publishing choices leave a
    caveat, which the status reports as a WARN.
    """
    if mode not in OUTSIDE_FLEET:
        raise BackendError(f"pso_lstm.outside_fleet must be one of {OUTSIDE_FLEET}, got {mode!r}")
    if meta.envelope is None or observer is None:
        return (), False
    envelope = FleetEnvelope.from_dict(meta.envelope)
    try:
        outside = envelope.outside(dataclasses.asdict(observer.params), observer.params.name)
    except EnvelopeError as err:
        raise BackendError(f"pso_lstm.observer_params_file: {err}") from None
    if not outside:
        return (), False
    where = (
        f"car {observer.params.name} outside {label}'s {envelope.cars} training cars "
        f"({'; '.join(outside)})"
    )
    if mode == "refuse":
        raise BackendError(f"pso_lstm.outside_fleet refuse: {where}")
    prior_only = publishes_prior(mode, meta.prior)
    action = "publishing the model's estimate"
    if prior_only:
        action = "publishing the UKF's estimate" if meta.prior == "ukf" else "publishing its prior"
    return (f"{where}: {action}",), prior_only
