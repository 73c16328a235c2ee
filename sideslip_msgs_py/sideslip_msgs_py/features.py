"""Model input channels and the feature sets of DESIGN.md, shared by estimator and trainer.

A channel name is the :class:`~sideslip_msgs_py.sample.SampleArrays` /
:class:`~sideslip_msgs_py.sample.VehicleSample` attribute that holds it, so a feature
list selects columns from either without a second mapping.
"""

from __future__ import annotations

from typing import Final

from .errors import ContractError

CHANNELS: Final[tuple[str, ...]] = (
    "x_v_mps",
    "y_v_mps",
    "x_a_mps2",
    "y_a_mps2",
    "yaw_rate_radps",
    "stl_m",
)
"""Every sensor channel a model may read, in the estimator window's column order:
X_v, Y_v [m/s] (body frame at the CG), X_a, Y_a [m/s²], ψ̇ [rad/s], STL [m]."""

FEATURE_SETS: Final[dict[str, tuple[str, ...]]] = {
    # The paper's six inputs. Y_v/X_v already gives β up to noise (see the kinematic
    # baseline), which is why `measurable` exists.
    "paper": CHANNELS,
    # What a production car measures: no lateral velocity.
    "measurable": ("x_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m"),
}


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
