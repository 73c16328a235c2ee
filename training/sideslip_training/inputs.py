"""What a model reads from a run: its input columns and its physics prior.

:class:`InputSpec` names the inputs (channels, derived and ``vehicle.*`` inputs of
:mod:`sideslip_msgs_py.model_inputs`) and the prior; it computes both over a whole run
with the same functions the estimator applies to its window. A run's car comes from its
bag's metadata (the simulator records it) or, for a recording without it, from the
spec's ``vehicle``. A model reading the UKF observer (``ukf.*`` inputs, ``ukf`` prior)
gets its columns from :mod:`.observer` (the filter with ``observer`` values, cached).
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py import model_inputs
from sideslip_msgs_py.vehicle_description import VehicleDescription, VehicleDescriptionError

from .config import DT_S
from .dataset import DatasetError

if TYPE_CHECKING:
    from .dataset import Run

FloatArray = npt.NDArray[np.float64]

CAR_SOURCES: Final = {
    "recorded": "each bag's own car record (a simulation's true parameters), else the given files",
    "given": "the given --vehicle / --observer-params for every bag, as the node is given "
    "them (sideslip-fit's described car)",
    "described": "each recorded car as its description alone tells it (the fleet's "
    "typical tyres, inertia and balance for the rest): the UKF a user who has only the "
    "description runs",
    "mixed": "half the recorded bags (fixed by a digest of the bag's name) as described, "
    "the other half recorded: trains a model that reads the UKF to correct it with right "
    "and with description-only parameters",
}
"""Where a run's car parameters (the UKF observer's, the ``vehicle.*`` inputs') come from."""


def add_car_argument(parser: argparse.ArgumentParser) -> None:
    """``--car`` (:data:`CAR_SOURCES`), as sideslip-train and sideslip-evaluate take it."""
    parser.add_argument(
        "--car",
        choices=list(CAR_SOURCES),
        default="recorded",
        help="where the car parameters of the UKF observer and the vehicle inputs come from "
        "for bags that record their car: " + "; ".join(f"{k}: {v}" for k, v in CAR_SOURCES.items()),
    )


def add_mirror_average_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """``--mirror-average auto|yes|no`` (the bare flag: yes; default auto, as the node's
    ``pso_lstm.mirror_average``; :func:`sideslip_msgs_py.data_source.mirror_average_on`).
    ``what``: what is averaged, as the help's opening words."""
    parser.add_argument(
        "--mirror-average",
        nargs="?",
        choices=["auto", "yes", "no"],
        const="yes",
        default="auto",
        help=f"{what} averaged with the mirror image, as the node's pso_lstm.mirror_average "
        "(a right turn answered as the mirrored left one; docs/evaluation/direction): yes "
        "(also the bare flag), no, or auto (default, as the node): for a model that records "
        "it learnt from simulated runs only",
    )


def add_car_files_arguments(parser: argparse.ArgumentParser) -> None:
    """``--vehicle``, ``--observer-params`` and ``--car``: the car a scored model is
    given, as sideslip-evaluate and sideslip-calibrate take them."""
    parser.add_argument(
        "--vehicle",
        type=Path,
        help="nominal parameters (YAML) of the car of bags that record none, for models "
        "that read the car",
    )
    parser.add_argument(
        "--observer-params",
        type=Path,
        metavar="UKF.yaml",
        help="the car's ukf params file for bags that record none, for models that read "
        "the UKF observer",
    )
    add_car_argument(parser)


@dataclass(frozen=True)
class InputSpec:
    """Inputs, prior and sample period of a model; ``vehicle`` is the car of runs whose
    bags do not record one (a real recording); ``observer`` the UKF's parameter values
    for a model that reads it (None: the back-end's defaults), ``observer_params_file``
    its ``ukf`` params file for runs whose bags record no car; ``car`` where the car's
    parameters come from for runs whose bags record one (:data:`CAR_SOURCES`)."""

    features: tuple[str, ...]
    prior: str = "none"
    dt_s: float = DT_S
    vehicle: VehicleDescription | None = None
    observer: Mapping[str, Any] | None = None
    observer_params_file: str | None = None
    car: str = "recorded"

    def __post_init__(self) -> None:
        if self.car not in CAR_SOURCES:
            raise DatasetError(f"car must be one of {', '.join(CAR_SOURCES)}, got {self.car!r}")
        try:
            object.__setattr__(self, "features", model_inputs.check_inputs(self.features))
            model_inputs.check_prior(self.prior)
        except model_inputs.ModelInputError as err:
            raise DatasetError(str(err)) from None
        if self.needs_observer:
            from . import observer

            values = observer.check_values(self.observer or {})
            object.__setattr__(self, "observer", values)
        elif self.observer is not None:
            raise DatasetError("observer values given for a model that does not read the UKF")

    @classmethod
    def of(cls, spec: InputSpec | Sequence[str]) -> InputSpec:
        """A spec, or plain channel names (no prior) as a spec."""
        return spec if isinstance(spec, InputSpec) else cls(tuple(spec))

    @property
    def needs_vehicle(self) -> bool:
        return model_inputs.needs_vehicle(self.features, self.prior)

    @property
    def needs_observer(self) -> bool:
        return model_inputs.needs_observer(self.features, self.prior)

    @property
    def channels(self) -> tuple[str, ...]:
        return model_inputs.required_channels(self.features, self.prior)

    def run_vehicle(self, run: Run) -> VehicleDescription | None:
        """The run's car: from its bag's metadata, else the spec's; None when not needed."""
        if not self.needs_vehicle:
            return None
        car = run.car_source or self.car
        recorded = None if car == "given" else run.run_metadata.get("vehicle")
        if recorded is not None:
            try:
                return VehicleDescription.from_mapping(recorded, f"{run.name}: vehicle")
            except VehicleDescriptionError as err:
                raise DatasetError(str(err)) from None
        if self.vehicle is None:
            raise DatasetError(
                f"{run.name}: the model reads the vehicle's nominal parameters, but "
                + ("the given car is asked for" if car == "given" else "the bag records no vehicle")
                + "; give one (a vehicle description YAML)"
            )
        return self.vehicle

    def columns(self, run: Run) -> dict[str, FloatArray]:
        """The run's channel columns, and the observer's when the model reads it."""
        columns = model_inputs.columns_of(run.samples, self.channels)
        if self.needs_observer:
            from . import observer

            assert self.observer is not None  # set in __post_init__
            columns.update(
                observer.columns(run, self.observer, self.observer_params_file, self.car)
            )
        return columns

    def inputs(self, run: Run) -> FloatArray:
        """(S, F) float64 input columns of the run (units of model_inputs)."""
        return model_inputs.input_matrix(self.columns(run), self.features, self.run_vehicle(run))

    def prior_rad(self, run: Run, window_steps: int) -> FloatArray:
        """(S,) β_prior [rad] of every sample (NaN before the first full window)."""
        return model_inputs.prior_series(self.columns(run), self.prior, window_steps, self.dt_s)
