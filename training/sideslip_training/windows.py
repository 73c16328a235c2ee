"""Windows over normalised runs, indexed rather than copied, for numpy and torch.

:class:`WindowIndex` holds the normalised samples of all runs back to back, plus the index
of the last sample of every valid window; a batch gathers its windows from that
(``ends[i] - T + 1 .. ends[i]``), so the windows themselves are never materialised
(428 k samples × 100 steps × 6 features would be 1 GB; the samples are 10 MB).
:class:`TorchWindows` is the same on a torch device, where the trainer gathers batches.

Units: features are z-scores (:class:`~.normalize.Normalizer`), ``beta_rad`` radians,
``stamp_ns`` int64 nanoseconds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from .dataset import DatasetError
from .normalize import Normalizer

if TYPE_CHECKING:
    import torch

    from .dataset import Run
    from .inputs import InputSpec

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class WindowIndex:
    """Normalised samples of all runs back to back and the windows over them.

    Window ``i`` is ``x[ends[i] - window_steps + 1 : ends[i] + 1]`` (oldest row first);
    its target is ``y[ends[i]]``, the normalised β of its last sample. Within a run,
    windows start at samples 0, stride, 2·stride, ... (so the first window of every run
    long enough is always included, the last sample only when the grid reaches it);
    windows that would cross the run's end or contain a non-finite feature, and windows
    whose target β is non-finite, are left out. Runs are never joined: a window never
    spans two runs (or two segments of a bag split at a gap).

    Attributes:
        x: (S, F) float32 normalised features, S = samples of all runs.
        y: (S,) float32 normalised target at each sample: β, or β − prior for a model
            with a prior (NaN where either is).
        prior_rad: (S,) float64 β_prior [rad] of each sample (0 without a prior).
        ends: (N,) int64 index into x of the last sample of each window.
        run_of_window: (N,) int64 index into ``run_names`` of each window's run.
        run_names: names of the runs, in order.
        run_starts: (R + 1,) int64 offsets: run r is ``x[run_starts[r]:run_starts[r+1]]``.
        stamp_ns: (S,) int64 stamp of each sample [ns].
        beta_rad: (S,) float64 ground-truth β [rad] (unrounded, for metrics).
        features, window_steps, stride: as built.
        notes: runs too short for one window, or with windows left out.
    """

    x: npt.NDArray[np.float32]
    y: npt.NDArray[np.float32]
    prior_rad: FloatArray
    ends: IntArray
    run_of_window: IntArray
    run_names: tuple[str, ...]
    run_starts: IntArray
    stamp_ns: IntArray
    beta_rad: FloatArray
    features: tuple[str, ...]
    window_steps: int
    stride: int
    notes: tuple[str, ...] = ()

    def __len__(self) -> int:
        return int(self.ends.shape[0])

    @classmethod
    def build(
        cls,
        runs: Sequence[Run],
        features: Sequence[str] | InputSpec,
        normalizer: Normalizer,
        window_steps: int = 100,
        stride: int = 1,
    ) -> WindowIndex:
        """Normalise ``runs`` with ``normalizer`` and index their windows.

        ``features``: channel names, or an :class:`~.inputs.InputSpec` (derived inputs,
        a prior: the target is then β − prior).

        Raises:
            DatasetError: features differ from the normalizer's, a run has no ground
                truth, or ``window_steps`` / ``stride`` < 1.
        """
        from .inputs import InputSpec

        spec = InputSpec.of(features)
        features = spec.features
        if features != normalizer.features:
            msg = f"features {features} differ from the normalizer's {normalizer.features}"
            raise DatasetError(msg)
        if window_steps < 1 or stride < 1:
            msg = f"window_steps and stride must be >= 1, got {window_steps} and {stride}"
            raise DatasetError(msg)
        xs, betas, priors, stamps, ends, owners, notes = [], [], [], [], [], [], []
        offset = 0
        starts = [0]
        for r, run in enumerate(runs):
            if not run.samples.has_truth:
                msg = f"WindowIndex.build: run {run.name} has no ground truth β"
                raise DatasetError(msg)
            raw = spec.inputs(run)
            beta = run.samples.beta_rad()
            prior = spec.prior_rad(run, window_steps)
            n = raw.shape[0]
            candidates = np.arange(window_steps - 1, n, stride, dtype=np.int64)
            bad = np.concatenate([[0], np.cumsum(~np.isfinite(raw).all(axis=1))])
            clean = (bad[candidates + 1] - bad[candidates + 1 - window_steps] == 0) & np.isfinite(
                beta[candidates] - prior[candidates]
            )
            valid = candidates[clean]
            if candidates.size == 0:
                notes.append(f"{run.name}: {n} samples, shorter than one window ({window_steps})")
            elif valid.size < candidates.size:
                notes.append(
                    f"{run.name}: {candidates.size - valid.size} of {candidates.size} windows "
                    "left out (non-finite feature or β)"
                )
            xs.append(raw)
            betas.append(beta)
            priors.append(prior)
            stamps.append(run.samples.stamp_ns)
            ends.append(valid + offset)
            owners.append(np.full(valid.shape, r, dtype=np.int64))
            offset += n
            starts.append(offset)
        width = len(features)
        x_all = np.concatenate(xs) if xs else np.empty((0, width))
        beta_all = np.concatenate(betas) if betas else np.empty(0)
        prior_all = np.concatenate(priors) if priors else np.empty(0)
        return cls(
            x=normalizer.apply_features(x_all).astype(np.float32),
            y=normalizer.apply_beta(beta_all - prior_all).astype(np.float32),
            prior_rad=prior_all,
            ends=np.concatenate(ends) if ends else np.empty(0, np.int64),
            run_of_window=np.concatenate(owners) if owners else np.empty(0, np.int64),
            run_names=tuple(run.name for run in runs),
            run_starts=np.array(starts, dtype=np.int64),
            stamp_ns=np.concatenate(stamps) if stamps else np.empty(0, np.int64),
            beta_rad=beta_all,
            features=features,
            window_steps=window_steps,
            stride=stride,
            notes=tuple(notes),
        )

    def batch(
        self, indices: npt.ArrayLike
    ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """Windows ``indices`` as X (B, T, F) and their targets Y (B,), both float32."""
        last = self.ends[np.asarray(indices, dtype=np.int64)]
        rows = last[:, None] + np.arange(1 - self.window_steps, 1, dtype=np.int64)
        return self.x[rows], self.y[last]

    def to_torch(self, device: str | torch.device = "cpu") -> TorchWindows:
        """The samples and window ends as tensors on ``device`` (about 24 B per sample)."""
        import torch

        dev = torch.device(device)
        return TorchWindows(
            x=torch.from_numpy(self.x).to(dev),
            y=torch.from_numpy(self.y).to(dev),
            ends=torch.from_numpy(self.ends).to(dev),
            offsets=torch.arange(1 - self.window_steps, 1, dtype=torch.int64, device=dev),
        )


@dataclass(frozen=True, eq=False)
class TorchWindows:
    """:class:`WindowIndex` on a torch device; batches are gathered where the data lives.

    Attributes:
        x: (S, F) float32 normalised features.
        y: (S,) float32 normalised β.
        ends: (N,) int64 last-sample index of each window.
        offsets: (T,) int64 ``-T+1 .. 0``.
    """

    x: torch.Tensor
    y: torch.Tensor
    ends: torch.Tensor
    offsets: torch.Tensor

    def __len__(self) -> int:
        return int(self.ends.shape[0])

    def batch(self, idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Windows ``idx`` (window numbers, any device) as X (B, T, F) and Y (B,)."""
        last = self.ends[idx.to(self.ends.device, non_blocking=True)]
        return self.x[last[:, None] + self.offsets], self.y[last]
