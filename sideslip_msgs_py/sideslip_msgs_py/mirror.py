"""A run mirrored left-right: the same car driven the other way round.

A passenger car is symmetric about its centre plane, so for every run it drives there is
a mirrored run it could drive just as well: the steering, the lateral velocity and
acceleration and the yaw rate change sign, the longitudinal ones do not, and so
β = atan2(v_y, v_x) changes sign exactly. Training on both doubles the data without a
metre more driving, and a network trained that way answers a left turn as it answers a
right one. Which channels change sign is the registry's ``lateral`` flag
(:mod:`.channels`); nothing here names a channel.

What mirroring cannot give: a car or a sensor that is not symmetric (a lateral
acceleration bias, a steering offset, tyre conicity) is mirrored with the run, so the
mirrored run shows the opposite offset. Training with both copies averages such an
offset out rather than learning it; a model that must learn one car's offsets from its
recordings should be compared with and without (``sideslip-train --mirror``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Final

import numpy as np
import numpy.typing as npt

from .channels import SENSOR, TRUTH
from .sample import SampleArrays

LATERAL_CHANNELS: Final = tuple(ch.name for ch in (*SENSOR, *TRUTH) if ch.lateral)
"""The columns that change sign under a left-right mirror (registry order)."""

ODD_INPUTS: Final = frozenset(
    {
        "tan_beta_kinematic", "beta_rate_radps", "y_a_g", "centripetal_g",
        "road_wheel_angle_rad", "understeer_angle_rad", "rear_kinematic_beta_rad",
        "ukf.beta_rad", "ukf.yaw_rate_innovation_radps",
        "ukf.lateral_acceleration_innovation_mps2",
    }
)  # fmt: skip
"""The derived and observer model inputs (:mod:`.model_inputs`) that change sign under a
left-right mirror; the others (speed, longitudinal acceleration, μ̂, the car's
parameters) keep it. Each input's parity is checked against its definition in the
tests, so a new input cannot be declared wrongly here."""


def input_signs(names: Sequence[str]) -> npt.NDArray[np.float64]:
    """Per model input: −1 where a left-right mirror negates it, +1 where it keeps it.
    The model inputs of a mirrored run are the signs times the run's own."""
    odd = ODD_INPUTS.union(LATERAL_CHANNELS)
    return np.array([-1.0 if name in odd else 1.0 for name in names])


def mirrored(samples: SampleArrays) -> SampleArrays:
    """``samples`` with every lateral column negated (stamps and the rest as they are).

    Mirroring twice gives the samples back exactly (negation is exact in floating point),
    and the mirrored run's β is exactly −β.
    """
    columns = {f.name: getattr(samples, f.name) for f in dataclasses.fields(samples)}
    for name in LATERAL_CHANNELS:
        if columns[name] is not None:
            columns[name] = -np.asarray(columns[name])
    return SampleArrays(**columns)
