"""The model artifact's metadata: what rebuilds and feeds the network, and its checks.

:class:`ModelMetadata` is stored as JSON under :data:`METADATA_KEY` in the
``.safetensors`` header (:mod:`sideslip_msgs_py.artifact` reads and writes the file);
construction checks every field and raises :class:`ArtifactError` naming it.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields
from datetime import UTC, datetime
from typing import Any, Final

import numpy as np

from .errors import ContractError
from .fleet_envelope import EnvelopeError, FleetEnvelope
from .model_inputs import (
    ModelInputError,
    check_inputs,
    check_prior,
    needs_observer,
    needs_vehicle,
    required_channels,
)
from .vehicle_description import VehicleDescription, VehicleDescriptionError

FORMAT_VERSION: Final = 1
VERSION_KEY: Final = "format_version"
"""``__metadata__`` key holding the format version as a decimal string."""
ARCHITECTURES: Final = ("lstm", "bilstm")
METADATA_KEY: Final = "sideslip.model"
"""``__metadata__`` key holding :class:`ModelMetadata` as JSON."""
VALIDATION_RMSE_KEY: Final = "val_rmse_deg"
"""``metrics`` key of the validation RMSE of β̂ [deg]; the estimator publishes its square
(in rad²) as the variance of β̂. Optional; when present a finite number >= 0."""


class ArtifactError(ContractError, ValueError):
    """A model artifact is malformed or does not match its metadata (message names the file)."""


class ArtifactExistsError(ArtifactError, FileExistsError):
    """The output artifact exists and ``force`` was not given."""


def _utc_now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _json_value(value: object, name: str) -> Any:
    """``value`` as it reads back from strict JSON (tuples → lists, numpy scalars → Python)."""

    def default(o: object) -> object:
        if isinstance(o, np.generic | np.ndarray):
            return o.tolist()
        raise TypeError(f"{type(o).__name__} is not JSON serialisable")

    try:
        text = json.dumps(value, allow_nan=False, default=default, sort_keys=True)
    except (TypeError, ValueError) as err:
        raise ArtifactError(f"model metadata: {name} must be strict JSON ({err})") from None
    return json.loads(text)


def _is_int(v: object) -> bool:
    return isinstance(v, int | np.integer) and not isinstance(v, bool)


def _is_real(v: object) -> bool:
    return isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool)


@dataclass(frozen=True)
class ModelMetadata:
    """Everything needed to rebuild and feed the network, stored in the artifact's header.

    Sequences are stored as tuples of Python floats and the JSON fields as what reads
    back from JSON, so a written and re-read metadata compares equal. Construction
    checks every field (:class:`ArtifactError` naming the field).
    """

    architecture: str
    """``lstm`` or ``bilstm`` (bidirectional; the head reads both directions' last step)."""
    hidden_units: int
    """H: hidden state size per direction."""
    layers: int
    """Stacked LSTM layers (layer k > 0 reads H, or 2H for bilstm, inputs)."""
    features: tuple[str, ...]
    """Input columns in order: contract channels, derived inputs or ``vehicle.*``
    conditioning inputs (:mod:`sideslip_msgs_py.model_inputs`)."""
    window_steps: int
    """Rows per window (the paper: 100)."""
    dt_s: float
    """Sample period the model was trained at [s] (the paper: 0.0025)."""
    feature_mean: tuple[float, ...]
    """Per-feature mean, in the feature's unit (m/s, m/s², rad/s, m)."""
    feature_std: tuple[float, ...]
    """Per-feature standard deviation (> 0), same units."""
    beta_mean: float
    """Mean of the training target β [rad]."""
    beta_std: float
    """Standard deviation of β [rad] (> 0)."""
    training_data_digest: str
    """Digest identifying the training data (e.g. sha256 over the bags' contents)."""
    metrics: dict[str, Any] = field(default_factory=dict, hash=False)
    """Evaluation results (JSON); :data:`VALIDATION_RMSE_KEY` is read by the estimator."""
    pso: dict[str, Any] | None = field(default=None, hash=False)
    """PSO result and settings (JSON), or None for a plain LSTM/BiLSTM."""
    created_utc: str = field(default_factory=_utc_now)
    """ISO 8601 UTC time of export (default: now, ``YYYY-MM-DDTHH:MM:SSZ``)."""
    provenance: dict[str, Any] = field(default_factory=dict, hash=False)
    """Free-form JSON: sideslip version, training command, git commit, seed, ..."""
    prior: str = "none"
    """Physics prior the network is a residual on (:data:`~.model_inputs.PRIORS`):
    β̂ = prior(window) + y · beta_std + beta_mean; ``none``: β̂ = y · beta_std + beta_mean."""
    vehicle: dict[str, Any] | None = field(default=None, hash=False)
    """Nominal parameters of the car the model is fitted to (a
    :class:`~.vehicle_description.VehicleDescription` as a dict), used when the model
    reads the vehicle and the deployment names none; None for a fleet model, which must
    be given the car at deployment."""
    observer: dict[str, Any] | None = field(default=None, hash=False)
    """Parameters of the ``ukf`` back-end (all but ``params_file``) that computed the
    ``ukf.*`` inputs or prior in training; deployment runs the same filter with the car's
    ``ukf`` params file. Required exactly when the model reads the observer. A file that
    does not record ``estimate_disturbance`` (written before it existed) reads as false."""
    uncertainty: dict[str, Any] | None = field(default=None, hash=False)
    """The per-sample standard deviation model
    (:class:`~sideslip_msgs_py.uncertainty.Uncertainty` as a dict), or None: the
    estimator then publishes the validation RMSE² as every sample's variance."""
    envelope: dict[str, Any] | None = field(default=None, hash=False)
    """The range of the training cars
    (:class:`~sideslip_msgs_py.fleet_envelope.FleetEnvelope` as a dict), recorded for
    models that read the UKF observer; the estimator checks the deployed car's ``ukf``
    params against it. None: not recorded (no check)."""
    format_version: int = FORMAT_VERSION

    def __post_init__(self) -> None:
        def fail(what: str) -> ArtifactError:
            return ArtifactError(f"model metadata: {what}")

        if not _is_int(self.format_version) or self.format_version != FORMAT_VERSION:
            raise fail(
                f"unknown format_version {self.format_version!r} (this reader knows "
                f"{FORMAT_VERSION})"
            )
        if self.architecture not in ARCHITECTURES:
            raise fail(f"unknown architecture {self.architecture!r} (known: {ARCHITECTURES})")
        for name in ("hidden_units", "layers", "window_steps"):
            v = getattr(self, name)
            if not _is_int(v) or v < 1:
                raise fail(f"{name} must be an integer >= 1, got {v!r}")
            object.__setattr__(self, name, int(v))
        if isinstance(self.features, str):
            raise fail(f"features must be a sequence of channel names, got {self.features!r}")
        features = tuple(self.features)
        if not features:
            raise fail("features is empty")
        try:
            check_inputs(features)
            check_prior(self.prior)
        except ModelInputError as err:
            raise fail(str(err)) from None
        object.__setattr__(self, "features", features)
        if self.vehicle is not None:
            try:
                desc = VehicleDescription.from_mapping(self.vehicle, "vehicle")
            except VehicleDescriptionError as err:
                raise fail(str(err)) from None
            object.__setattr__(self, "vehicle", desc.to_dict())
        for name, positive in (("feature_mean", False), ("feature_std", True)):
            v = getattr(self, name)
            try:
                values = tuple(np.asarray(v, dtype=np.float64).reshape(-1).tolist())
            except (TypeError, ValueError):
                raise fail(f"{name} must be a sequence of numbers, got {v!r}") from None
            if len(values) != len(features):
                raise fail(f"{name} has {len(values)} values for {len(features)} features")
            for feat, x in zip(features, values, strict=True):
                if not math.isfinite(x) or (positive and x <= 0.0):
                    need = "finite and > 0" if positive else "finite"
                    raise fail(f"{name} of {feat} must be {need}, got {x!r}")
            object.__setattr__(self, name, values)
        for name, positive in (("dt_s", True), ("beta_mean", False), ("beta_std", True)):
            v = getattr(self, name)
            if not _is_real(v) or not math.isfinite(v) or (positive and v <= 0):
                need = "finite and > 0" if positive else "finite"
                raise fail(f"{name} must be a number, {need}, got {v!r}")
            object.__setattr__(self, name, float(v))
        for name in ("training_data_digest", "created_utc"):
            if not isinstance(getattr(self, name), str):
                raise fail(f"{name} must be a string, got {getattr(self, name)!r}")
        if needs_observer(features, self.prior) != (self.observer is not None):
            raise fail(
                "observer (the UKF's parameters) must be given exactly when the inputs or "
                f"the prior read the UKF observer (inputs {list(features)}, prior {self.prior})"
            )
        for name in ("metrics", "pso", "provenance", "observer"):
            v = getattr(self, name)
            if v is None and name in ("pso", "observer"):
                continue
            if not isinstance(v, dict):
                raise fail(f"{name} must be a JSON object (dict), got {type(v).__name__}")
            object.__setattr__(self, name, _json_value(v, name))
        if self.observer is not None and "estimate_disturbance" not in self.observer:
            # Files from before the UKF's disturbance state (2026-12-06) were trained on
            # the filter without it: deployment must run that filter, not today's default.
            object.__setattr__(self, "observer", {**self.observer, "estimate_disturbance": False})
        if self.uncertainty is not None:
            from .uncertainty import Uncertainty, UncertaintyError

            try:
                unc = Uncertainty.from_dict(self.uncertainty)
            except UncertaintyError as err:
                raise fail(str(err)) from None
            object.__setattr__(self, "uncertainty", unc.to_dict())
        if self.envelope is not None:
            try:
                env = FleetEnvelope.from_dict(self.envelope)
            except EnvelopeError as err:
                raise fail(str(err)) from None
            object.__setattr__(self, "envelope", env.to_dict())
        rmse = self.metrics.get(VALIDATION_RMSE_KEY)
        if rmse is not None and not (_is_real(rmse) and math.isfinite(rmse) and rmse >= 0):
            raise fail(f"metrics.{VALIDATION_RMSE_KEY} must be a finite number >= 0, got {rmse!r}")

    @property
    def directions(self) -> int:
        """1 for lstm, 2 for bilstm."""
        return 2 if self.architecture == "bilstm" else 1

    @property
    def needs_vehicle(self) -> bool:
        """Whether the inputs or the prior read the car's nominal parameters."""
        return needs_vehicle(self.features, self.prior)

    @property
    def needs_observer(self) -> bool:
        """Whether the inputs or the prior read the UKF observer's columns."""
        return needs_observer(self.features, self.prior)

    @property
    def channels(self) -> tuple[str, ...]:
        """The contract channels the model reads (inputs and prior)."""
        return required_channels(self.features, self.prior)

    def to_header(self) -> dict[str, str]:
        """The safetensors ``__metadata__`` map."""
        text = json.dumps(asdict(self), allow_nan=False, sort_keys=True)
        return {VERSION_KEY: str(self.format_version), METADATA_KEY: text}

    @classmethod
    def from_header(cls, header: dict[str, str] | None) -> ModelMetadata:
        """Parse a ``__metadata__`` map (raises :class:`ArtifactError` without a path)."""
        if not header or METADATA_KEY not in header or VERSION_KEY not in header:
            have = sorted(header) if header else []
            msg = (
                f"missing metadata: the header needs {VERSION_KEY!r} and {METADATA_KEY!r} "
                f"(has {have}); not a sideslip model"
            )
            raise ArtifactError(msg)
        if header[VERSION_KEY] != str(FORMAT_VERSION):
            msg = (
                f"unknown format version {header[VERSION_KEY]!r} (this reader knows "
                f"{FORMAT_VERSION}); a newer sideslip wrote it?"
            )
            raise ArtifactError(msg)
        try:
            data = json.loads(header[METADATA_KEY])
        except ValueError as err:
            raise ArtifactError(f"{METADATA_KEY} is not valid JSON ({err})") from None
        if not isinstance(data, dict):
            raise ArtifactError(f"{METADATA_KEY} must be a JSON object")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ArtifactError(f"{METADATA_KEY} has unknown key(s) {unknown}")
        try:
            return cls(**data)
        except TypeError as err:  # a required key is missing
            raise ArtifactError(f"{METADATA_KEY}: {err}") from None
