"""Fine-tuned weights moved back toward the start model's: θ = θ₀ + α (θ_ft − θ₀).

Weight-space ensembling of a fine-tuned network with the one it started from ("WiSE-FT",
Wortsman et al., CVPR 2022). A fine-tuning on a few minutes of one car's recordings fits
those drives and forgets part of what the start model knew about other driving: from the
fleet model retrained on the tuned UKF, ``sideslip-fit --bags`` gained on each
recording's own test part but lost on other drives of five held-out cars of six
(docs/evaluation/fit-bags). Half way between the two (α = 0.5) was better than either
end on validation cars' other drives (same page, "Half way back to the start").

Only meaningful when both networks read the same z-scored inputs: the fine-tuning kept
the start model's normalisation (``--normalization keep``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # no torch at import: sideslip-fit checks --interpolate before loading it
    import torch

    from .model import SideslipNet


def check_alpha(alpha: float) -> float:
    """``alpha`` if it lies in (0, 1], else ValueError naming it."""
    if not (math.isfinite(alpha) and 0.0 < alpha <= 1.0):
        raise ValueError(f"--interpolate must be within (0, 1], got {alpha!r}")
    return alpha


def interpolate_toward(
    model: SideslipNet, start: Mapping[str, torch.Tensor], alpha: float
) -> SideslipNet:
    """``model`` with its weights set to ``start + alpha · (model − start)`` (in place;
    returned). ``alpha`` 1 leaves the fine-tuned weights, 0 would give the start's.
    ``start`` must have ``model``'s parameter names and shapes (KeyError/RuntimeError)."""
    check_alpha(alpha)
    tuned = model.state_dict()
    if set(tuned) != set(start):
        raise KeyError(f"start weights name {sorted(set(start) ^ set(tuned))} differently")
    mixed = {
        name: start[name].to(t.device, t.dtype) + alpha * (t - start[name].to(t.device, t.dtype))
        for name, t in tuned.items()
    }
    model.load_state_dict(mixed, strict=True)
    return model
