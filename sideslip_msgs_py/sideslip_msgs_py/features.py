"""Model input channels and the feature sets of DESIGN.md, shared by estimator and trainer.

A channel name is the :class:`~sideslip_msgs_py.sample.SampleArrays` /
:class:`~sideslip_msgs_py.sample.VehicleSample` attribute that holds it, so a feature
list selects columns from either without a second mapping.
"""

from __future__ import annotations

from typing import Final

from . import channels as registry
from .errors import ContractError

CHANNELS: Final[tuple[str, ...]] = tuple(ch.name for ch in registry.SENSOR if ch.model_input)
"""Every sensor channel a model may read, in the estimator window's column order (the
registry's model inputs, :mod:`.channels`): X_v, Y_v [m/s] (body frame at the CG),
X_a, Y_a [m/s²], ψ̇ [rad/s], STL [m]."""

FEATURE_SET_NAMES: Final[tuple[str, ...]] = (
    # The paper's six inputs. Y_v/X_v already gives β up to noise (see the kinematic
    # baseline), which is why `measurable` exists.
    "paper",
    # What a production car measures: no lateral velocity.
    "measurable",
)

FEATURE_SETS: Final[dict[str, tuple[str, ...]]] = {
    name: tuple(ch.name for ch in registry.SENSOR if name in ch.feature_sets)
    for name in FEATURE_SET_NAMES
}
"""Each feature set's channels, in :data:`CHANNELS` order (a channel's ``feature_sets``)."""


class FeatureError(ContractError, ValueError):
    """An unknown feature set or channel name."""


def feature_set(name: str) -> tuple[str, ...]:
    """The channels of a named feature set (raises :class:`FeatureError` when unknown)."""
    try:
        return FEATURE_SETS[name]
    except KeyError:
        msg = f"unknown feature set {name!r} (known: {', '.join(FEATURE_SETS)})"
        raise FeatureError(msg) from None


def channel_indices(channels: tuple[str, ...] | list[str]) -> tuple[int, ...]:
    """Column indices of ``channels`` in :data:`CHANNELS` order."""
    unknown = [c for c in channels if c not in CHANNELS]
    if unknown:
        msg = f"unknown channel(s) {unknown} (known: {', '.join(CHANNELS)})"
        raise FeatureError(msg)
    return tuple(CHANNELS.index(c) for c in channels)
