"""Z-score statistics of the training runs: features and β, to and from JSON.

:class:`Normalizer` is fitted on the training runs only (:func:`~.splits.split_runs`
first), applied to every window (:mod:`.windows`) and saved in the model artifact's
metadata, so the estimator normalises its input exactly as training did.

Units: ``mean`` and ``std`` are in each channel's unit (those of
:data:`sideslip_msgs_py.features.CHANNELS`: m/s, m/s², rad/s, m); β statistics in radians.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.model_inputs import ModelInputError, check_inputs
from sideslip_msgs_py.timing import WINDOW_STEPS

from .dataset import BETA, DatasetError

if TYPE_CHECKING:
    from .dataset import Run
    from .inputs import InputSpec

FloatArray = npt.NDArray[np.float64]

STD_FLOOR: Final = 1e-9
"""A channel whose standard deviation is at most this (in its own unit) is constant in
the training data: it gets std 1.0 (so it is only centred) and a note in the normalizer."""


@dataclass(frozen=True, eq=False)
class Normalizer:
    """Z-score statistics: z = (x − mean) / std per feature, and likewise for β.

    Attributes:
        features: channel names, in model input order.
        mean: per-feature mean, in the channel's unit (float64, read-only).
        std: per-feature standard deviation (population), in the channel's unit; 1.0 for
            a channel constant in the training data (std ≤ :data:`STD_FLOOR`), see notes.
        beta_mean: mean of β [rad].
        beta_std: standard deviation of β [rad] (1.0 when β is constant).
        notes: channels that got std 1.0 and why.
    """

    features: tuple[str, ...]
    mean: FloatArray
    std: FloatArray
    beta_mean: float
    beta_std: float
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "features", check_inputs(self.features))
        except ModelInputError as err:
            raise DatasetError(str(err)) from None
        for name in ("mean", "std"):
            arr = np.array(getattr(self, name), dtype=np.float64)
            if arr.shape != (len(self.features),) or not np.isfinite(arr).all():
                msg = f"Normalizer.{name} must be {len(self.features)} finite values, got {arr}"
                raise DatasetError(msg)
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "beta_mean", float(self.beta_mean))
        object.__setattr__(self, "beta_std", float(self.beta_std))
        stds = [*self.std.tolist(), self.beta_std]
        if not (all(s > 0.0 for s in stds) and math.isfinite(self.beta_mean + self.beta_std)):
            msg = f"Normalizer: std must be positive and finite, got {stds}"
            raise DatasetError(msg)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Normalizer):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]

    @classmethod
    def fit(
        cls,
        runs: Sequence[Run],
        features: Sequence[str] | InputSpec,
        window_steps: int = WINDOW_STEPS,
    ) -> Normalizer:
        """Statistics over every finite sample of ``runs`` (pass the training runs only).

        ``features``: channel names, or an :class:`~.inputs.InputSpec` (derived inputs, a
        prior). With a prior, the "β" statistics are those of the target β − prior over
        the samples that have a full window. Each column uses its own finite values (a
        NaN in one does not remove the sample from the others). Raises DatasetError when
        a column or β has none.
        """
        from .inputs import InputSpec

        spec = InputSpec.of(features)
        features = spec.features
        if not runs:
            raise DatasetError("Normalizer.fit: no runs")
        columns = [*features, BETA]
        values: dict[str, list[FloatArray]] = {c: [] for c in columns}
        for run in runs:
            if not run.samples.has_truth:
                msg = f"Normalizer.fit: run {run.name} has no ground truth β"
                raise DatasetError(msg)
            x = spec.inputs(run)
            for j, c in enumerate(features):
                values[c].append(x[:, j])
            values[BETA].append(run.samples.beta_rad() - spec.prior_rad(run, window_steps))
        means: list[float] = []
        stds: list[float] = []
        notes: list[str] = []
        for c in columns:
            v = np.concatenate(values[c])
            v = v[np.isfinite(v)]
            if v.size == 0:
                msg = f"Normalizer.fit: {c} has no finite value in {len(runs)} run(s)"
                raise DatasetError(msg)
            mean, std = float(v.mean()), float(v.std())
            if std <= STD_FLOOR:
                notes.append(
                    f"{c} is constant ({mean:g}) in the training data: std set to 1.0, "
                    "so it is only centred"
                )
                std = 1.0
            means.append(mean)
            stds.append(std)
        return cls(
            features,
            np.array(means[:-1]),
            np.array(stds[:-1]),
            means[-1],
            stds[-1],
            tuple(notes),
        )

    def apply_features(self, x: npt.ArrayLike) -> FloatArray:
        """Normalise features ``x`` (..., F), columns in :attr:`features` order → float64."""
        arr = np.asarray(x, dtype=np.float64)
        if arr.ndim == 0 or arr.shape[-1] != len(self.features):
            want = len(self.features)
            msg = f"apply_features: last axis must hold {want} features, got shape {arr.shape}"
            raise DatasetError(msg)
        return (arr - self.mean) / self.std

    def apply_beta(self, beta_rad: npt.ArrayLike) -> FloatArray:
        """β [rad] → normalised β."""
        return (np.asarray(beta_rad, dtype=np.float64) - self.beta_mean) / self.beta_std

    def invert_beta(self, z: npt.ArrayLike) -> FloatArray:
        """Normalised β → β [rad]."""
        return np.asarray(z, dtype=np.float64) * self.beta_std + self.beta_mean

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (floats round-trip exactly through JSON)."""
        return {
            "features": list(self.features),
            "mean": self.mean.tolist(),
            "std": self.std.tolist(),
            "beta_mean": self.beta_mean,
            "beta_std": self.beta_std,
            "notes": list(self.notes),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Normalizer:
        """Inverse of :meth:`to_dict`; unknown or missing keys are an error."""
        keys = {"features", "mean", "std", "beta_mean", "beta_std", "notes"}
        unknown, missing = set(data) - keys, keys - {"notes"} - set(data)
        if unknown or missing:
            msg = f"normalizer: unknown keys {sorted(unknown)}, missing keys {sorted(missing)}"
            raise DatasetError(msg)
        try:
            return cls(
                tuple(str(f) for f in data["features"]),
                np.array(data["mean"], dtype=np.float64),
                np.array(data["std"], dtype=np.float64),
                float(data["beta_mean"]),
                float(data["beta_std"]),
                tuple(str(n) for n in data.get("notes", ())),
            )
        except (TypeError, ValueError) as err:
            if isinstance(err, DatasetError):
                raise
            msg = f"normalizer: bad value: {err}"
            raise DatasetError(msg) from None
