"""What the vehicle's sensors measure in one time step, as records and as columns.

Frame and signs: body frame at the centre of gravity (CG), REP-103: x forward, y left,
z up, yaw counter-clockwise positive. Sideslip β = atan2(v_y, v_x) > 0 when the car
slides to the left. Time stamps are integer nanoseconds (ROS time: simulated or wall).
One step of the simulator is 2.5 ms (400 Hz).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Final

import numpy as np
import numpy.typing as npt

from .errors import SampleArraysError

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

KMH_TO_MPS: Final = 1.0 / 3.6


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


@dataclass(frozen=True, slots=True)
class VehicleSample:
    """One time step of what the sensors measure (the paper's six inputs plus STL rate).

    Attributes:
        stamp_ns: measurement time [ns]; every message of the step carries it.
        x_v_mps: longitudinal velocity X_v [m/s].
        y_v_mps: lateral velocity Y_v [m/s].
        x_a_mps2: longitudinal acceleration X_a [m/s²].
        y_a_mps2: lateral acceleration Y_a [m/s²].
        yaw_rate_radps: yaw rate ψ̇ [rad/s].
        stl_m: steering rack travel STL [m] (positive steers left).
        stl_rate_mps: steering rack speed [m/s].
        truth: exact motion when known (simulator), else None.
    """

    stamp_ns: int
    x_v_mps: float
    y_v_mps: float
    x_a_mps2: float
    y_a_mps2: float
    yaw_rate_radps: float
    stl_m: float
    stl_rate_mps: float
    truth: GroundTruth | None = None


SENSOR_CHANNELS: Final[tuple[str, ...]] = (
    "x_v_mps",
    "y_v_mps",
    "x_a_mps2",
    "y_a_mps2",
    "yaw_rate_radps",
    "stl_m",
    "stl_rate_mps",
)
"""Float channels of a sample, in :class:`VehicleSample` field order."""

TRUTH_CHANNELS: Final[tuple[str, ...]] = (
    "truth_v_x_mps",
    "truth_v_y_mps",
    "truth_yaw_rate_radps",
)
"""Ground-truth channels of :class:`SampleArrays` (all present or all None)."""


@dataclass(frozen=True, eq=False)
class SampleArrays:
    """Columnar samples: equal-length 1-D arrays, one row per time step.

    Channels have the units of :class:`VehicleSample`. ``stamp_ns`` is int64 and strictly
    increasing; every other channel is float64. The truth channels are either all
    arrays or all None. Construction validates and converts (copies only when the
    dtype differs); arrays are made read-only so the frozen record stays frozen.
    """

    stamp_ns: IntArray
    x_v_mps: FloatArray
    y_v_mps: FloatArray
    x_a_mps2: FloatArray
    y_a_mps2: FloatArray
    yaw_rate_radps: FloatArray
    stl_m: FloatArray
    stl_rate_mps: FloatArray
    truth_v_x_mps: FloatArray | None = None
    truth_v_y_mps: FloatArray | None = None
    truth_yaw_rate_radps: FloatArray | None = None

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
            assert self.truth_v_x_mps is not None
            assert self.truth_v_y_mps is not None
            assert self.truth_yaw_rate_radps is not None
            truth = GroundTruth(
                float(self.truth_v_x_mps[i]),
                float(self.truth_v_y_mps[i]),
                float(self.truth_yaw_rate_radps[i]),
            )
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
            columns["truth_v_x_mps"] = np.array([t.v_x_mps for t in truths if t], np.float64)
            columns["truth_v_y_mps"] = np.array([t.v_y_mps for t in truths if t], np.float64)
            columns["truth_yaw_rate_radps"] = np.array(
                [t.yaw_rate_radps for t in truths if t], np.float64
            )
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


@dataclass(frozen=True, slots=True)
class SensorNoiseSigma:
    """Standard deviation σ of each sensor's Gaussian noise, in SI units.

    Used by the simulator to add noise and by the message mapping to fill covariances
    (variance = σ²).

    Attributes:
        velocity_mps: σ of X_v and Y_v [m/s].
        acceleration_mps2: σ of X_a and Y_a [m/s²].
        yaw_rate_radps: σ of ψ̇ [rad/s].
        stl_m: σ of the steering rack travel [m].
    """

    velocity_mps: float
    acceleration_mps2: float
    yaw_rate_radps: float
    stl_m: float

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (math.isfinite(value) and value >= 0.0):
                msg = f"SensorNoiseSigma.{f.name} must be finite and >= 0, got {value!r}"
                raise ValueError(msg)

    @classmethod
    def paper(cls) -> SensorNoiseSigma:
        """The paper's noise: 1 km/h, 0.1 m/s², 0.2 deg/s, 1 mm (converted to SI)."""
        return cls(
            velocity_mps=1.0 * KMH_TO_MPS,
            acceleration_mps2=0.1,
            yaw_rate_radps=math.radians(0.2),
            stl_m=1.0e-3,
        )

    @classmethod
    def none(cls) -> SensorNoiseSigma:
        """No noise (ground-truth-quality sensors): all σ = 0."""
        return cls(0.0, 0.0, 0.0, 0.0)
