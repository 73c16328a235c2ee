"""What the vehicle's sensors measure in one time step, as records and as columns.

Frame and signs: body frame at the centre of gravity (CG), REP-103: x forward, y left,
z up, yaw counter-clockwise positive. Sideslip β = atan2(v_y, v_x) > 0 when the car
slides to the left. Time stamps are integer nanoseconds (ROS time: simulated or wall).
One step of the simulator is 2.5 ms (400 Hz).

The channel fields of :class:`VehicleSample` and :class:`SampleArrays` and the σ fields
of :class:`SensorNoiseSigma` come from the registry (:mod:`.channels`), in its order;
the classes here hold what is not per channel (stamps, truth, validation).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Final, TypeVar

import numpy as np
import numpy.typing as npt

from . import channels as registry
from .channels import KMH_TO_MPS
from .errors import SampleArraysError

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

registry.validate()

SENSOR_CHANNELS: Final[tuple[str, ...]] = tuple(ch.name for ch in registry.SENSOR)
"""Float channels of a sample, in :class:`VehicleSample` field order."""

TRUTH_CHANNELS: Final[tuple[str, ...]] = tuple(ch.name for ch in registry.TRUTH)
"""Ground-truth channels of :class:`SampleArrays` (all present or all None)."""

_Cls = TypeVar("_Cls", bound=type)


_NO_DEFAULT: Final = object()


def _fields_from_registry(
    names: Iterable[str],
    annotation: str,
    *,
    after: str | None = None,
    default: object = _NO_DEFAULT,
    doc: str = "",
) -> Callable[[_Cls], _Cls]:
    """Class decorator (under ``@dataclass``): one field per name, annotated
    ``annotation`` (with ``default`` when given), inserted after the field ``after``
    (None: at the end); ``doc`` is appended to the docstring."""

    def insert(cls: _Cls) -> _Cls:
        own = inspect.get_annotations(cls)
        added = dict.fromkeys(names, annotation)
        merged: dict[str, object] = {}
        for key, value in own.items():
            merged[key] = value
            if key == after:
                merged.update(added)
        if after is None:
            merged.update(added)
        cls.__annotations__ = merged
        if default is not _NO_DEFAULT:
            for name in added:
                setattr(cls, name, default)
        cls.__doc__ = (cls.__doc__ or "") + doc
        return cls

    return insert


@dataclass(frozen=True, slots=True)
class GroundTruth:
    """Exact body motion at the CG (simulator only).

    Attributes:
        v_x_mps: longitudinal velocity v_x [m/s].
        v_y_mps: lateral velocity v_y [m/s], positive to the left.
        yaw_rate_radps: yaw rate ψ̇ [rad/s], counter-clockwise positive.
    """

    v_x_mps: float
    v_y_mps: float
    yaw_rate_radps: float

    @property
    def beta_rad(self) -> float:
        """Sideslip angle β = atan2(v_y, v_x) [rad]."""
        return math.atan2(self.v_y_mps, self.v_x_mps)


_SENSOR_DOC: Final = "\n    Channels (from the registry):\n" + registry.describe(registry.SENSOR)


@dataclass(frozen=True, slots=True)
@_fields_from_registry(SENSOR_CHANNELS, "float", after="stamp_ns", doc=_SENSOR_DOC)
class VehicleSample:
    """One time step of what the sensors measure (the paper's six inputs plus STL rate).

    Fields: ``stamp_ns``, then one float per sensor channel of the registry (in its
    order, so positional construction follows it), then ``truth``.

    Attributes:
        stamp_ns: measurement time [ns]; every message of the step carries it.
        truth: exact motion when known (simulator), else None.
    """

    stamp_ns: int
    truth: GroundTruth | None = None

    if TYPE_CHECKING:  # the channel fields, added from the registry

        def __getattr__(self, name: str) -> float: ...


@dataclass(frozen=True, eq=False)
@_fields_from_registry(TRUTH_CHANNELS, "FloatArray | None", default=None)
@_fields_from_registry(SENSOR_CHANNELS, "FloatArray", after="stamp_ns", doc=_SENSOR_DOC)
class SampleArrays:
    """Columnar samples: equal-length 1-D arrays, one row per time step.

    Channels have the units of :class:`VehicleSample`. ``stamp_ns`` is int64 and strictly
    increasing; every other channel is float64. The truth channels are either all
    arrays or all None. Construction validates and converts (copies only when the
    dtype differs); arrays are made read-only so the frozen record stays frozen.

    Fields: ``stamp_ns``, the sensor channels, then the truth channels (default None),
    all in registry order.
    """

    stamp_ns: IntArray

    if TYPE_CHECKING:  # the channel fields, added from the registry

        def __getattr__(self, name: str) -> FloatArray: ...

    def __post_init__(self) -> None:
        stamps = _column(self, "stamp_ns", np.int64)
        n = stamps.shape[0]
        for name in SENSOR_CHANNELS:
            _column(self, name, np.float64, n)
        present = [getattr(self, name) is not None for name in TRUTH_CHANNELS]
        if any(present) and not all(present):
            given = [name for name, p in zip(TRUTH_CHANNELS, present, strict=True) if p]
            msg = f"SampleArrays: truth channels must be given together, got only {given}"
            raise SampleArraysError(msg)
        if all(present):
            for name in TRUTH_CHANNELS:
                _column(self, name, np.float64, n)
        if n > 1:
            steps = np.diff(stamps)
            if (bad := np.flatnonzero(steps <= 0)).size:
                i = int(bad[0])
                msg = (
                    "SampleArrays.stamp_ns must be strictly increasing: "
                    f"row {i + 1} has {int(stamps[i + 1])} ns after {int(stamps[i])} ns"
                )
                raise SampleArraysError(msg)

    def __len__(self) -> int:
        return int(self.stamp_ns.shape[0])

    def __eq__(self, other: object) -> bool:
        """Exact equality of every channel (NaN equals NaN)."""
        if not isinstance(other, SampleArrays):
            return NotImplemented
        for f in fields(self):
            a, b = getattr(self, f.name), getattr(other, f.name)
            if (a is None) != (b is None):
                return False
            if a is not None and not np.array_equal(a, b, equal_nan=a.dtype.kind == "f"):
                return False
        return True

    __hash__ = None  # type: ignore[assignment]  # mutable-content arrays: not hashable

    @property
    def has_truth(self) -> bool:
        """True when the ground-truth channels are present."""
        return self.truth_v_x_mps is not None

    def row(self, i: int) -> VehicleSample:
        """Row ``i`` (negative indices count from the end) as a :class:`VehicleSample`."""
        n = len(self)
        if not -n <= i < n:
            msg = f"SampleArrays.row({i}): index out of range for {n} samples"
            raise IndexError(msg)
        truth = None
        if self.has_truth:
            exact = {_truth_attr(n): float(getattr(self, n)[i]) for n in TRUTH_CHANNELS}
            truth = GroundTruth(**exact)
        values = {name: float(getattr(self, name)[i]) for name in SENSOR_CHANNELS}
        return VehicleSample(stamp_ns=int(self.stamp_ns[i]), truth=truth, **values)

    @classmethod
    def from_samples(cls, samples: Sequence[VehicleSample]) -> SampleArrays:
        """Columns from records; truth must be set on all samples or on none."""
        with_truth = [s.truth is not None for s in samples]
        if any(with_truth) and not all(with_truth):
            i = with_truth.index(not with_truth[0])
            msg = f"SampleArrays.from_samples: sample {i} differs from sample 0 in having truth"
            raise SampleArraysError(msg)
        columns: dict[str, npt.NDArray[np.generic]] = {
            "stamp_ns": np.array([s.stamp_ns for s in samples], dtype=np.int64),
        }
        for name in SENSOR_CHANNELS:
            columns[name] = np.array([getattr(s, name) for s in samples], dtype=np.float64)
        if samples and all(with_truth):
            truths = [s.truth for s in samples]
            for name in TRUTH_CHANNELS:
                attr = _truth_attr(name)
                columns[name] = np.array([getattr(t, attr) for t in truths if t], np.float64)
        return cls(**columns)  # type: ignore[arg-type]

    def beta_rad(self) -> FloatArray:
        """Ground-truth sideslip β = atan2(v_y, v_x) [rad] per row."""
        if self.truth_v_x_mps is None or self.truth_v_y_mps is None:
            msg = "SampleArrays.beta_rad(): these samples carry no ground truth"
            raise SampleArraysError(msg)
        # math.atan2 per element (not np.arctan2, whose SIMD variants may differ by an ulp)
        # so that the columns agree bit for bit with GroundTruth.beta_rad and the bag's
        # ground-truth sideslip messages.
        return np.fromiter(
            map(math.atan2, self.truth_v_y_mps.tolist(), self.truth_v_x_mps.tolist()),
            dtype=np.float64,
            count=len(self),
        )


def _truth_attr(column: str) -> str:
    """The :class:`GroundTruth` attribute of a truth column (``truth_v_x_mps`` → ``v_x_mps``)."""
    return column.removeprefix(registry.TRUTH_PREFIX)


def _column(
    arrays: SampleArrays, name: str, dtype: type[np.generic], n: int | None = None
) -> npt.NDArray[np.generic]:
    """Validate and normalise one column in place of the frozen dataclass field."""
    value = getattr(arrays, name)
    try:
        col = np.asarray(value)
        if col.dtype != dtype:
            if dtype is np.int64 and col.dtype.kind not in "iu":
                msg = f"SampleArrays.{name} must hold integers (ns), got dtype {col.dtype}"
                raise SampleArraysError(msg)
            col = col.astype(dtype)
    except (TypeError, ValueError) as err:
        if isinstance(err, SampleArraysError):
            raise
        msg = f"SampleArrays.{name} cannot be converted to {np.dtype(dtype)}: {err}"
        raise SampleArraysError(msg) from None
    if col.ndim != 1:
        msg = f"SampleArrays.{name} must be 1-D, got shape {col.shape}"
        raise SampleArraysError(msg)
    if n is not None and col.shape[0] != n:
        msg = f"SampleArrays.{name} has {col.shape[0]} rows, stamp_ns has {n}"
        raise SampleArraysError(msg)
    if col is value:
        col = col.view()  # do not make the caller's array read-only
    col.flags.writeable = False
    object.__setattr__(arrays, name, col)
    return col


_NOISE_DOC: Final = "\n    Attributes (from the registry):\n" + "\n".join(
    f"        {n.name}: σ of {n.of} [{n.unit}]." for n in registry.NOISE
)


@dataclass(frozen=True, slots=True)
@_fields_from_registry([n.name for n in registry.NOISE], "float", doc=_NOISE_DOC)
class SensorNoiseSigma:
    """Standard deviation σ of each sensor's Gaussian noise, in SI units.

    Used by the simulator to add noise and by the message mapping to fill covariances
    (variance = σ²). One field per :data:`~.channels.NOISE` key, in its order.
    """

    if TYPE_CHECKING:  # the σ fields, added from the registry

        def __getattr__(self, name: str) -> float: ...

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (math.isfinite(value) and value >= 0.0):
                msg = f"SensorNoiseSigma.{f.name} must be finite and >= 0, got {value!r}"
                raise ValueError(msg)

    @classmethod
    def paper(cls) -> SensorNoiseSigma:
        """The paper's noise: 1 km/h, 0.1 m/s², 0.2 deg/s, 1 mm (converted to SI)."""
        return cls(**{n.name: n.paper for n in registry.NOISE})

    @classmethod
    def none(cls) -> SensorNoiseSigma:
        """No noise (ground-truth-quality sensors): all σ = 0."""
        return cls(**{n.name: 0.0 for n in registry.NOISE})


__all__ = [
    "KMH_TO_MPS",
    "SENSOR_CHANNELS",
    "TRUTH_CHANNELS",
    "GroundTruth",
    "SampleArrays",
    "SensorNoiseSigma",
    "VehicleSample",
]
