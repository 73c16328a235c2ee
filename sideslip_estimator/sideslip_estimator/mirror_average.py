"""A network averaged with its own mirror image: the same answer to a left turn as to a right.

A car is symmetric (:mod:`sideslip_msgs_py.mirror`): driven the other way round, every
lateral signal and β change sign. A network learns that only as far as its training
drives teach it, and the fleet's drives start most manoeuvres to the same side, so the
shipped UKF-anchored networks err more on mirrored drives (docs/evaluation/direction).
Averaged with its mirror image, a network is exactly odd:

    β̂ = prior + ½ (r(x) − r(M x)),

with r the network's residual on its prior (all priors are β estimates, odd themselves)
and M x the mirrored inputs, ``input_signs ⊙ x``. In the network's z-scored units:
z_m = s ⊙ z + (s − 1) ⊙ mean / std, and the output y_eff = ½ (y − y_m) − beta_mean /
beta_std denormalises to that half difference, so the caller's denormalisation and prior
stay as they are. Cost: a second network on every sample (the filter runs once).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.artifact import ModelMetadata
from sideslip_msgs_py.mirror import input_signs


class MirrorMap:
    """The mirror of z-scored input rows and the combined output, for one model."""

    def __init__(self, meta: ModelMetadata) -> None:
        signs = input_signs(meta.features)
        mean = np.asarray(meta.feature_mean, dtype=np.float64)
        std = np.asarray(meta.feature_std, dtype=np.float64)
        self._signs = signs
        self._shift = (signs - 1.0) * mean / std
        self._offset = meta.beta_mean / meta.beta_std

    def inputs(self, z: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """z-scored inputs of the mirrored sample(s) (the last axis: the model's inputs)."""
        return self._signs * z + self._shift

    def output(self, y: float, y_mirror: float) -> float:
        """The z-scored output whose β is the prior plus the residuals' half difference."""
        return 0.5 * (y - y_mirror) - self._offset


class MirrorAveragedStream:
    """Two streaming engines of one network, one fed the mirrored rows
    (:class:`~sideslip_estimator.streaming.StreamingLstm`'s interface)."""

    def __init__(self, engine, mirror_engine, meta: ModelMetadata) -> None:  # type: ignore[no-untyped-def]
        self._engine = engine
        self._mirror = mirror_engine
        self._map = MirrorMap(meta)
        self.per_window_recurrences = engine.per_window_recurrences

    def reset(self) -> None:
        self._engine.reset()
        self._mirror.reset()

    def push(self, row: npt.ArrayLike) -> float | None:
        z = np.asarray(row, dtype=np.float64)
        y = self._engine.push(z)
        y_mirror = self._mirror.push(self._map.inputs(z))
        if y is None or y_mirror is None:
            return None
        return self._map.output(y, y_mirror)


class MirrorAveragedWindow:
    """A per-window network (``window → y``) averaged with its mirror image."""

    def __init__(self, net: Callable[[npt.NDArray[np.float64]], float], meta: ModelMetadata):
        self._net = net
        self._map = MirrorMap(meta)

    def __call__(self, z: npt.NDArray[np.float64]) -> float:
        return self._map.output(self._net(z), self._net(self._map.inputs(z)))
