"""The contract's time base, in one place: samples 2.5 ms apart (400 Hz, the paper's
step) and the paper's window of 100 samples (250 ms). The simulator publishes at this
step, models are trained at it unless told otherwise, and the estimator counts missing
steps against it.
"""

from __future__ import annotations

from typing import Final

STEP_S: Final = 0.0025
"""Sample period [s]."""
STEP_NS: Final = 2_500_000
"""Sample period [ns] (exactly STEP_S)."""
RATE_HZ: Final = 400.0
"""Sample rate [Hz] (1 / STEP_S)."""
WINDOW_STEPS: Final = 100
"""Samples in a model's window (WINDOW_STEPS · STEP_S = 250 ms)."""
