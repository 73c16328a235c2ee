"""PSO-LSTM / BiLSTM back-end: the trained network of a model artifact over the window.

The artifact (:mod:`sideslip_msgs_py.artifact`, written by ``sideslip-train``) holds
float32 weights and the metadata: architecture, feature names and order, z-score
statistics, window length and sample period. Nothing in it is executed: the network is
rebuilt from the metadata and the weights are read by name. Start-up refuses
(:class:`BackendError`) a file that is missing or malformed, a window length other than
the model's, or a feature the window lacks.

Per sample: the model's inputs, z-scored in float64 and rounded to float32, go through
the LSTM; the head reads its output at the window's last step (the paper's Fig. 5) and
β̂ [rad] = y · beta_std + beta_mean (+ the prior). Three engines compute the same thing:

* ``numba`` (default) and ``numpy``: :class:`~sideslip_estimator.streaming.StreamingLstm`
  (per member for a merged model: :mod:`~sideslip_estimator.streaming_members`).
  Every window in flight reads the same new sample, so each call pushes the newest row
  once and all windows advance with one batched LSTM step; the oldest one is complete
  and is the estimate. ``numba`` runs that step as one compiled float32 call per layer
  (:mod:`sideslip_estimator.lstm_kernel`; 2-3× faster), ``numpy`` as numpy calls in
  float64 (exact up to float64 rounding: the reference). Both equal the trainer's
  network within 1e-6 rad (tested on random and shipped models) and need no torch.
  Without numba installed, ``numba`` falls back to ``numpy`` (``engine`` says which
  runs). Each call must bring exactly one new row (the estimator's contract); rows
  that do not continue the previous call refill the engine from the window.
* ``torch``: the whole window through ``torch.lstm`` per call, bit for bit what
  ``sideslip_training``'s ``SideslipNet`` gives. A BiLSTM with two or more layers
  always takes it (its upper layers read the reverse direction, which depends on where
  the window ends, so nothing can be shared between windows).

Sample period: the model assumes rows ``dt_s`` apart (``metadata.dt_s``, the paper's
2.5 ms). The back-end does not check the rows' rate; the estimator reads
:attr:`sample_period_s` and keeps its input line at that step.

Inputs and prior (:mod:`sideslip_msgs_py.model_inputs`): a model may read derived
inputs, its car's nominal parameters and the UKF observer, and may be a residual on a
physics prior over the window; the same functions compute them here as in training.
Where the car and the observer come from, and what happens outside the training cars:
:mod:`.model_context`. With ``model_file`` empty the default follows what is given:
``fleet_ukf_paper`` when ``observer_params_file`` names the car's file, else
``fleet_lstm_paper`` (:func:`.model_files.default_model`).

Beyond a fine-tuned model's recordings, ``pso_lstm.beyond_fit_range`` may publish the
model it started from instead (run beside it): see :mod:`.model_files`.

Variance: from the model's per-sample uncertainty (:mod:`sideslip_msgs_py.uncertainty`,
``sideslip-calibrate``) at the newest row, widened while the window reaches beyond a
fine-tuned model's recordings; a model without one (the paper reproductions) publishes
the square of its stored validation RMSE (``metrics["val_rmse_deg"]``, in radians²), or
:data:`DEFAULT_SIGMA_RAD` (1°) squared when it has none either.

torch is imported only when the ``torch`` engine is built (:mod:`.torch_window`), never
by this module's import, so the registry, the other back-ends and the default engine
work without it.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from typing import Final

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.artifact import VALIDATION_RMSE_KEY, denormalize_beta
from sideslip_msgs_py.data_source import mirror_average_on
from sideslip_msgs_py.model_inputs import (
    OBSERVER_COLUMNS,
    columns_of_rows,
    input_matrix,
    prior_of_window,
)
from sideslip_msgs_py.vehicle_description import VehicleDescription

from ..inputs import X_V as _X_V
from ..inputs import Y_A as _Y_A
from ..inputs import YAW_RATE as _YAW_RATE
from ..mirror_average import MirrorAveragedStream, MirrorAveragedWindow
from ..streaming_members import numba_available, streaming_engine
from .base import BackendError, Estimate, parameter_values
from .model_context import fleet_check, observer_for, published_uncertainty, vehicle_for
from .model_files import (
    BEYOND_FIT_RANGE,
    default_model,
    hands_over,
    read_model,
    start_model_name,
)
from .pso_lstm_parameters import PSO_LSTM_PARAMETERS
from .torch_window import TorchWindow

ENGINES: Final = ("numba", "numpy", "torch")


class _Unset:
    """No observer output given (:meth:`PsoLstmBackend._update` runs the filter)."""


_UNSET: Final = _Unset()
DEFAULT_SIGMA_RAD: Final = math.radians(1.0)
"""1-σ of β̂ [rad] published when the artifact has no validation RMSE: about three
times the paper's LSTM test RMSE (Table 5), so a fusion filter trusts it modestly."""


class PsoLstmBackend:
    """A trained LSTM/BiLSTM from a model artifact (see the module docstring)."""

    name = "pso_lstm"
    parameters = PSO_LSTM_PARAMETERS

    def __init__(
        self,
        values: Mapping[str, object],
        window_steps: int,
        *,
        car: VehicleDescription | None = None,
    ) -> None:
        """``car``: the car to read when ``vehicle_file`` is empty and the model stores
        none (a start model reading its fine-tuned model's car)."""
        v = parameter_values(self.name, self.parameters, values)
        threads = int(v["threads"])
        if threads < 1:
            raise BackendError(f"pso_lstm.threads must be >= 1, got {threads}")
        observer_file = str(v["observer_params_file"])
        tensors, meta, label = read_model(str(v["model_file"]), default_model(observer_file))
        self._label = label
        if window_steps != meta.window_steps:
            msg = (
                f"pso_lstm.model_file {label}: the model reads {meta.window_steps}-step windows "
                f"but the estimator's window_steps is {window_steps}; set "
                f"window_steps:={meta.window_steps}"
            )
            raise BackendError(msg)
        self._vehicle = (
            car
            if car is not None and meta.needs_vehicle and not v["vehicle_file"]
            else vehicle_for(meta, str(v["vehicle_file"]), label)
        )
        self._channels = meta.channels
        self.channels = tuple(meta.channels)
        self._observer = observer_for(meta, observer_file, label, window_steps)
        self.caveats, self._prior_only = fleet_check(
            meta, self._observer, str(v["outside_fleet"]), label
        )
        self._observed: deque[tuple[float, ...]] = deque(maxlen=window_steps)

        self.meta = meta
        self.dt_s = meta.dt_s
        """Sample period the model was trained at [s] (also ``sample_period_s``)."""
        self.window_steps = window_steps
        self.threads = threads
        rmse_deg = meta.metrics.get(VALIDATION_RMSE_KEY)
        sigma = math.radians(rmse_deg) if rmse_deg is not None else DEFAULT_SIGMA_RAD
        self.variance_rad2 = sigma * sigma
        """The variance of models without an uncertainty model (validation RMSE²)."""
        self._uncertainty, described_sigma = published_uncertainty(meta, self._observer)
        ukf_alone = self._prior_only and meta.prior == "ukf"
        self._mean = np.asarray(meta.feature_mean, dtype=np.float64)
        self._std = np.asarray(meta.feature_std, dtype=np.float64)

        engine = str(v["engine"])
        if engine not in ENGINES:
            raise BackendError(f"pso_lstm.engine must be one of {ENGINES}, got {engine!r}")
        if engine == "numba" and not numba_available():
            engine = "numpy"
        kernel = "numba" if engine == "numba" else "numpy"
        self._stream = streaming_engine(tensors, meta, kernel=kernel)
        if engine != "torch" and self._stream.per_window_recurrences > 0:
            engine = "torch"  # a stacked BiLSTM recomputes its windows: torch is faster
        self.engine = engine
        """``numba`` or ``numpy`` (the streaming engine) or ``torch`` (the whole window
        per sample): the one that runs."""
        self._window_net = TorchWindow(tensors, meta, threads) if engine == "torch" else None
        try:
            self.mirror_average = mirror_average_on(v["mirror_average"], meta.provenance)
        except ValueError as err:
            raise BackendError(f"pso_lstm.mirror_average {err}") from None
        if self.mirror_average:  # the network and its mirror image (..mirror_average)
            mirror = streaming_engine(tensors, meta, kernel=kernel)
            self._stream = MirrorAveragedStream(self._stream, mirror, meta)
            if self._window_net is not None:
                self._window_net = MirrorAveragedWindow(self._window_net, meta)
        self._rows_pushed = 0
        self._last_stamp = 0
        self._start = self._start_backend(v, label)
        """The model this one was fine-tuned from, published beyond the fit range."""
        self._shared_observer = (
            self._start is not None
            and self._observer is not None
            and self._start._observer is not None
            and self._start.meta.observer == meta.observer
        )
        """The start model reads this model's filter (the same settings and car file)."""
        if self._shared_observer:
            assert self._start is not None
            # One filter object: the start's observer rows read its state (innovations)
            # after this model's update of it.
            self._start._observer = self._observer
        self.model_id = (
            f"pso_lstm({label}: {meta.architecture} {meta.layers}x{meta.hidden_units}, "
            f"features {','.join(meta.features)}, data {meta.training_data_digest[:12]}, "
            f"engine {engine}"
            + (", averaged with its mirror image" if self.mirror_average else "")
            + (f", observer {self._observer.model_id}" if self._observer is not None else "")
            + (", outside its training cars: the UKF's estimate" if self._prior_only else "")
            # Outside the training cars a UKF-residual model publishes the UKF's own σ.
            + (", σ for a described car file" if described_sigma and not ukf_alone else "")
            + (
                f", beyond its recordings: {self._start.label}'s estimate"
                + (" (its UKF's, outside its training cars)" if self._start._prior_only else "")
                if self._start is not None
                else ""
            )
            + ")"
        )

    def _start_backend(self, v: Mapping[str, object], label: str) -> PsoLstmBackend | None:
        """The start model's back-end when ``beyond_fit_range`` asks for it (see the module
        docstring); the same car files, engine and threads."""
        mode = str(v["beyond_fit_range"])
        if mode not in BEYOND_FIT_RANGE:
            raise BackendError(
                f"pso_lstm.beyond_fit_range must be one of {BEYOND_FIT_RANGE}, got {mode!r}"
            )
        fit = self._uncertainty.fit_range if self._uncertainty is not None else None
        if mode == "start" and fit is None:
            raise BackendError(
                f"pso_lstm.beyond_fit_range start: {label} records no range of recordings "
                "(it was not fine-tuned on a car's recordings by sideslip-fit --bags)"
            )
        if not hands_over(mode, fit):
            return None
        start_file = str(v["start_model_file"]) or start_model_name(self.meta) or ""
        if not start_file:
            if mode == "auto":
                return None
            raise BackendError(
                f"pso_lstm.beyond_fit_range start: {label} names no shipped start model "
                f"with its training data ({self.meta.provenance.get('init', 'none')}); set "
                "pso_lstm.start_model_file"
            )
        values = {**v, "model_file": start_file, "beyond_fit_range": "model"}
        values["start_model_file"] = ""
        # The fitted model's car passed its own checks; the start model's range of cars
        # may not hold it, but refusing the node for the fall-back would be worse.
        if values["outside_fleet"] == "refuse":
            values["outside_fleet"] = "auto"
        try:
            start = PsoLstmBackend(values, self.window_steps, car=self._vehicle)
            if start.dt_s != self.dt_s or start.channels != self.channels:
                raise BackendError(
                    f"its step or inputs differ from {label}'s; give the model {label} was "
                    "fine-tuned from (pso_lstm.start_model_file)"
                )
        except BackendError as err:
            message = f"pso_lstm.beyond_fit_range start model {start_file}: {err}"
            if mode == "start":
                raise BackendError(message) from None
            # auto: the fitted model's own estimate beyond the range, and a WARN.
            self.caveats = (*self.caveats, f"{message}; publishing {label}'s own, σ widened")
            return None
        self.caveats = (
            *self.caveats,
            *(f"beyond_fit_range start model: {c}" for c in start.caveats),
        )
        return start

    @property
    def label(self) -> str:
        """The model file's short name."""
        return self._label

    @property
    def sample_period_s(self) -> float:
        """The step [s] the model needs its inputs at (the Backend protocol's name)."""
        return self.dt_s

    def reset(self) -> None:
        """Restart the streaming engine's windows and the observer (if any)."""
        self._stream.reset()
        self._rows_pushed = 0
        if self._observer is not None:
            self._observer.reset()
            self._observed.clear()
        if self._start is not None:
            self._start.reset()

    def update(
        self, rows: npt.NDArray[np.float64], stamps_ns: npt.NDArray[np.int64]
    ) -> Estimate | None:
        if self._start is None:
            return self._update(rows, stamps_ns)
        # The start model sees every sample, so that its windows are current when the
        # window leaves the recordings' range. Both read the same filter (same settings,
        # same car file): it runs once, for half the cost of two.
        if self._shared_observer:
            assert self._observer is not None
            seen = self._observer.update(rows, stamps_ns)
            start = self._start._update(rows, stamps_ns, seen)
            own = self._update(rows, stamps_ns, seen)
        else:
            start = self._start.update(rows, stamps_ns)
            own = self._update(rows, stamps_ns)
        if own is None or not own.beyond_fit_range:
            return own
        return None if start is None else Estimate(start.beta_rad, start.variance_rad2, True)

    def _update(
        self,
        rows: npt.NDArray[np.float64],
        stamps_ns: npt.NDArray[np.int64],
        seen: Estimate | _Unset | None = _UNSET,
    ) -> Estimate | None:
        """:meth:`update` of this model alone; ``seen``: the observer's output for this
        sample when the caller ran it (a start model sharing the filter)."""
        if self._observer is not None:
            # The filter sees every sample, also while the window fills.
            if isinstance(seen, _Unset):
                seen = self._observer.update(rows, stamps_ns)
            if self._prior_only and self.meta.prior == "ukf":
                return seen  # outside the training cars: the UKF's estimate and variance
            self._observed.append(self._observer.observer_row(seen))
        if self._window_net is None and not self._prior_only:
            # The engine gives None until the window is full and NaN for a window with a
            # non-finite input (an observer row without an estimate): no estimate.
            y = self._push(rows, stamps_ns)
            if y is None or not math.isfinite(y):
                return None
            if self.meta.prior == "none":
                return Estimate(denormalize_beta(y, self.meta), *self._variance(rows))
        elif rows.shape[0] < self.window_steps or (
            self._observer is not None and len(self._observed) < self.window_steps
        ):
            return None
        columns = columns_of_rows(rows[-self.window_steps :], self._channels)
        if self._observer is not None:
            observed = np.array(self._observed)
            if not np.isfinite(observed).all():
                return None
            for j, name in enumerate(OBSERVER_COLUMNS):
                columns[name] = observed[:, j]
        prior = 0.0
        if self.meta.prior != "none":
            prior = prior_of_window(columns, self.meta.prior, self.dt_s)
            if not math.isfinite(prior):
                return None
            if self._prior_only:
                return Estimate(prior, *self._variance(rows))
        if self._window_net is not None:
            x = input_matrix(columns, self.meta.features, self._vehicle)
            y = self._window_net((x - self._mean) / self._std)
            if not math.isfinite(y):
                return None
        return Estimate(denormalize_beta(y, self.meta) + prior, *self._variance(rows))

    def _variance(self, rows: npt.NDArray[np.float64]) -> tuple[float, bool]:
        """The published variance [rad²]: the model's uncertainty at the newest row, or
        the validation RMSE² for a model without one; and whether the window reached
        beyond the driving the model was fitted on (its σ then widened)."""
        if self._uncertainty is None:
            return self.variance_rad2, False
        if self._uncertainty.fit_range is not None:
            return self._uncertainty.variance_of_window(
                rows[:, _X_V], rows[:, _Y_A], rows[:, _YAW_RATE]
            )
        row = rows[-1]
        return self._uncertainty.variance_of(
            float(row[_X_V]), float(row[_Y_A]), float(row[_YAW_RATE])
        ), False

    def _push(
        self, rows: npt.NDArray[np.float64], stamps_ns: npt.NDArray[np.int64]
    ) -> float | None:
        """The streaming engine's output after the newest row. Each call must bring one
        new row (the estimator's contract); if the rows do not continue what was pushed
        (a caller that skipped a call or restarted without :meth:`reset`), the engine is
        refilled from the window's rows, so the result is still the window's."""
        n = rows.shape[0]
        continues = n == min(self._rows_pushed + 1, self.window_steps) and (
            n == 1 or int(stamps_ns[-2]) == self._last_stamp
        )
        if not continues:
            self._stream.reset()
            self._rows_pushed = 0
            for k in range(n - 1):
                self._push_row(rows, k)
        self._last_stamp = int(stamps_ns[-1])
        return self._push_row(rows, n - 1)

    def _push_row(self, rows: npt.NDArray[np.float64], k: int) -> float | None:
        """Push row k of ``rows`` (z-scored model inputs) into the streaming engine."""
        columns = columns_of_rows(rows[k : k + 1], self._channels)
        if self._observer is not None:
            # The observer's value for row k: its history is aligned with the rows' end.
            back = rows.shape[0] - k
            got = self._observed[-back] if back <= len(self._observed) else None
            for j, name in enumerate(OBSERVER_COLUMNS):
                columns[name] = np.array([got[j] if got is not None else math.nan])
        x = input_matrix(columns, self.meta.features, self._vehicle)[0]
        self._rows_pushed = min(self._rows_pushed + 1, self.window_steps)
        return self._stream.push((x - self._mean) / self._std)
