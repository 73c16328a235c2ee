"""``sideslip-calibrate``: give a model a per-sample standard deviation that means what it
says (:mod:`sideslip_msgs_py.uncertainty`), fitted on validation bags, never on test ones.

The validation runs are split by bag into two halves (seeded): the model's errors on
the first fit the variance coefficients by Gaussian likelihood; the second half fixes
the conformal scale, so that ±z·σ (z = 1.96 for 95 %) holds the asked share of its
samples. The calibrated model is the same network with ``uncertainty`` in its metadata
(and the calibration's figures in ``metrics``); the estimator then publishes that σ² in
``/sideslip/twist`` instead of the validation RMSE².
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.artifact import ArtifactError, read_artifact, write_artifact
from sideslip_msgs_py.data_source import mirror_average_on
from sideslip_msgs_py.topic_map import TopicMap, TopicMapError
from sideslip_msgs_py.uncertainty import TERMS, Uncertainty, terms
from sideslip_msgs_py.vehicle_description import VehicleDescription, VehicleDescriptionError

from .cli_errors import EXIT_BAD_INPUT
from .dataset import DatasetError, Run, load_runs
from .evaluate import predict_run
from .export import load_model
from .init_model import InitError, resolve
from .inputs import add_car_files_arguments, add_mirror_average_argument
from .splits import split_runs

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Errors:
    """A model's errors [rad] per sample, with the inputs of the uncertainty terms and
    each sample's run index."""

    err: FloatArray
    v: FloatArray
    ay: FloatArray
    r: FloatArray
    run: npt.NDArray[np.int64]
    beyond: npt.NDArray[np.bool_] | None = None
    """Per sample, for a model whose σ has a fit range: its window reached beyond it
    (computed on the whole run, as the node does; the scored samples lack the first
    window's)."""

    def variance(self, unc: Uncertainty) -> FloatArray:
        """σ² [rad²] of ``unc`` at these samples (the model's own window flags)."""
        return unc.variance(self.v, self.ay, self.r, self.run, beyond=self.beyond)

    @classmethod
    def of_runs(cls, runs: Sequence[Run], model, meta, **car: Any) -> Errors:  # type: ignore[no-untyped-def]
        """The model's errors on ``runs`` (samples with a full window and a finite β̂);
        ``car``: :func:`~.evaluate.predict_run`'s ``vehicle``, ``observer_params_file``
        and ``car``, for bags that record no car or to give every run the same files."""
        w = meta.window_steps
        fit = (
            None if meta.uncertainty is None else Uncertainty.from_dict(meta.uncertainty).fit_range
        )
        keys = ("err", "v", "ay", "r", "run", "beyond")
        parts: dict[str, list[npt.NDArray[Any]]] = {k: [] for k in keys}
        for i, run in enumerate(runs):
            est = predict_run(model, meta, run, **car)
            s = run.samples
            ref = s.beta_rad()[w - 1 :]
            ok = np.isfinite(est) & np.isfinite(ref)
            parts["err"].append((est - ref)[ok])
            parts["v"].append(s.x_v_mps[w - 1 :][ok])
            parts["ay"].append(s.y_a_mps2[w - 1 :][ok])
            parts["r"].append(s.yaw_rate_radps[w - 1 :][ok])
            parts["run"].append(np.full(int(ok.sum()), i))
            if fit is not None:
                beyond = fit.window_beyond(s.x_v_mps, s.y_a_mps2, s.yaw_rate_radps)
                parts["beyond"].append(beyond[w - 1 :][ok])
        arrays = [np.concatenate(parts[k]) for k in keys[:-1]]
        errors = cls.from_arrays(*arrays)
        if fit is None:
            return errors
        return replace(errors, beyond=np.concatenate(parts["beyond"]))

    @classmethod
    def from_arrays(
        cls,
        err: FloatArray,
        x_v_mps: FloatArray,
        y_a_mps2: FloatArray,
        yaw_rate_radps: FloatArray,
        run: npt.NDArray[np.int64] | None = None,
    ) -> Errors:
        """Errors given directly (``run``: each sample's run index; default all run 0)."""
        e, v, ay, r = (
            np.asarray(a, dtype=np.float64) for a in (err, x_v_mps, y_a_mps2, yaw_rate_radps)
        )
        runs = np.zeros(e.size, np.int64) if run is None else np.asarray(run, dtype=np.int64)
        return cls(e, v, ay, r, runs)

    @classmethod
    def concatenate(cls, parts: Sequence[tuple[Errors, int]]) -> Errors:
        """Several sets of errors as one: each part with the number of runs it was made
        from, its runs numbered on after the previous parts' (what :meth:`of_runs` gives
        for all the runs in that order, each part scored by its own model)."""
        if not parts:
            raise ValueError("no errors to concatenate")
        if len({p.beyond is not None for p, _ in parts}) > 1:
            raise ValueError("errors with and without fit-range flags cannot be concatenated")
        offsets = np.cumsum([0, *(n for _, n in parts[:-1])])

        def cat(name: str) -> npt.NDArray[Any]:
            return np.concatenate([getattr(p, name) for p, _ in parts])

        run = np.concatenate([p.run + off for (p, _), off in zip(parts, offsets, strict=True)])
        beyond = None if parts[0][0].beyond is None else cat("beyond")
        return cls(cat("err"), cat("v"), cat("ay"), cat("r"), run, beyond)

    def select(self, indices: Sequence[int]) -> Errors:
        """The samples of the runs ``indices`` (indices into the runs these errors were
        made from), in the order given and renumbered 0..: what :meth:`of_runs` gives for
        that subset of the runs."""
        rows = [np.flatnonzero(self.run == i) for i in indices]
        take = np.concatenate(rows) if rows else np.zeros(0, np.int64)
        run = np.repeat(np.arange(len(rows), dtype=np.int64), [r.size for r in rows])
        beyond = None if self.beyond is None else self.beyond[take]
        return Errors(self.err[take], self.v[take], self.ay[take], self.r[take], run, beyond)

    def __len__(self) -> int:
        return int(self.err.size)


def fit_coefficients(errors: Errors) -> tuple[float, ...]:
    """Coefficients c ≥ 0 of σ² = Σ c·terms maximising the Gaussian likelihood of the
    errors (optimised over log c; a term the data do not need goes to ~0)."""
    from scipy.optimize import minimize

    t = terms(errors.v, errors.ay, errors.r)
    e2 = errors.err**2
    # Start: the mean squared error spread evenly over the terms' typical sizes.
    start = np.log(np.mean(e2) / (len(TERMS) * np.maximum(t.mean(axis=0), 1e-12)))

    def nll(log_c: FloatArray) -> float:
        var = t @ np.exp(log_c)
        return float(0.5 * np.mean(np.log(var) + e2 / var))

    result = minimize(nll, start, method="Nelder-Mead", options={"maxiter": 4000, "fatol": 1e-10})
    return tuple(float(x) for x in np.exp(result.x))


def z_of(coverage: float) -> float:
    """The two-sided standard normal quantile: ±z holds ``coverage`` of N(0, 1)."""
    from scipy.stats import norm

    return float(norm.ppf(0.5 + coverage / 2.0))


def conformal_scale(errors: Errors, coefficients: Sequence[float], coverage: float) -> float:
    """The scale s such that |err| ≤ z·s·σ for the (finite-sample corrected) share
    ``coverage`` of the samples."""
    sigma = np.sqrt(terms(errors.v, errors.ay, errors.r) @ np.asarray(coefficients))
    return scale_of_ratios(np.abs(errors.err) / sigma, coverage)


def scale_of_ratios(ratios: FloatArray, coverage: float) -> float:
    """The scale s such that ratio ≤ z·s for the (finite-sample corrected) share
    ``coverage`` of ``ratios`` (|err| / σ per sample): split conformal."""
    ratio = np.sort(ratios)
    n = ratio.size
    k = min(n - 1, math.ceil((n + 1) * coverage) - 1)
    return float(ratio[k]) / z_of(coverage)


def coverage_of(errors: Errors, unc: Uncertainty) -> tuple[float, FloatArray]:
    """Share of samples within ±z·σ, pooled and per run."""
    inside = np.abs(errors.err) <= z_of(unc.coverage) * np.sqrt(errors.variance(unc))
    per_run = np.array([inside[errors.run == i].mean() for i in np.unique(errors.run)])
    return float(inside.mean()), per_run


def calibrate(
    runs: Sequence[Run],
    model,
    meta,
    *,
    coverage: float = 0.95,
    seed: int = 0,  # type: ignore[no-untyped-def]
    scale_only: bool = False,
    car: dict[str, Any] | None = None,
    errors: Errors | None = None,
) -> tuple[Uncertainty, dict[str, float]]:
    """The uncertainty model for ``model`` from validation ``runs`` and its figures.

    ``scale_only``: keep the coefficients of the model's own uncertainty (fitted on a
    fleet) and fix only the conformal scale, on all of ``runs`` (one car's recordings:
    its error level, from minutes of data); ``car``: see :meth:`Errors.of_runs`;
    ``errors``: the model's errors on ``runs`` (:meth:`Errors.of_runs` with ``car``) when
    the caller has them already, so that the model is not run over the bags again."""
    car = car or {}
    position = {id(r): i for i, r in enumerate(runs)}

    def errors_of(subset: Sequence[Run]) -> Errors:
        if errors is None:
            return Errors.of_runs(subset, model, meta, **car)
        return errors.select([position[id(r)] for r in subset])

    if scale_only:
        if meta.uncertainty is None:
            raise DatasetError(
                "--scale-only keeps the model's σ terms, but this model has none: "
                "calibrate it on validation bags first"
            )
        coefficients = tuple(Uncertainty.from_dict(meta.uncertainty).coefficients)
        fit_runs, scale_runs = list(runs), list(runs)
        fit_errors = scale_errors = errors_of(runs)
        if len(scale_errors) < 100:
            raise DatasetError("too few scored samples to calibrate (fewer than 100)")
    else:
        fit_runs, scale_runs = split_runs(runs, 0.5, seed)
        fit_errors = errors_of(fit_runs)
        scale_errors = errors_of(scale_runs)
        if len(fit_errors) < 100 or len(scale_errors) < 100:
            raise DatasetError("too few scored samples to calibrate (fewer than 100 per half)")
        coefficients = fit_coefficients(fit_errors)
    # The range of the network's fine-tuning data stays what it was: keep it (a fitted
    # model calibrated again must not lose the widening beyond it).
    kept = None if meta.uncertainty is None else Uncertainty.from_dict(meta.uncertainty).fit_range
    scale = conformal_scale(scale_errors, coefficients, coverage)
    unc = Uncertainty(coefficients, scale, coverage, fit_range=kept)
    pooled, per_run = coverage_of(scale_errors, unc)
    const = math.sqrt(float(np.mean(fit_errors.err**2)))
    const_inside = np.abs(scale_errors.err) <= z_of(coverage) * const
    const_runs = np.array(
        [const_inside[scale_errors.run == i].mean() for i in np.unique(scale_errors.run)]
    )
    report = {
        "coverage_asked": coverage,
        "scale_only": float(scale_only),
        "fit_bags": float(len({r.bag for r in fit_runs})),
        "scale_bags": float(len({r.bag for r in scale_runs})),
        "coverage_scale_half": pooled,
        "coverage_per_run_min": float(per_run.min()),
        "coverage_per_run_p10": float(np.quantile(per_run, 0.1)),
        "coverage_per_run_median": float(np.median(per_run)),
        "constant_sigma_coverage_per_run_min": float(const_runs.min()),
        "constant_sigma_coverage_per_run_median": float(np.median(const_runs)),
    }
    return unc, report


def described_kinds(runs: Sequence[Run], meta, car: dict[str, Any]) -> set[bool]:  # type: ignore[no-untyped-def]
    """For each kind of UKF file ``runs`` are read with, whether it was made from a
    description (``axles_from: description``): {True} where all were, {False} where
    none was or the model reads no UKF, both for a mix (``--car mixed``)."""
    if not meta.needs_observer:
        return {False}
    from .observer import axles_from

    return {
        axles_from(r, car["observer_params_file"], car=car["car"]) == "description" for r in runs
    }


def for_described_files(runs: Sequence[Run], meta, car: dict[str, Any]) -> bool:  # type: ignore[no-untyped-def]
    """Whether the calibration is the σ for car files made from a description: every
    run's UKF file is one (``--car described``, or ``--car given`` with such a file).

    A mix of both kinds (``--car mixed``) calibrates the model's own σ, which the node
    publishes with every file, as a training with ``--car mixed`` fits it
    (``fleet_ukf_described``). Raises DatasetError for a mix where the model keeps a σ
    for described files beside its own (one σ cannot be both), or for described files
    where the model has no σ of its own to keep."""
    kinds = described_kinds(runs, meta, car)
    unc = None if meta.uncertainty is None else Uncertainty.from_dict(meta.uncertainty)
    if kinds != {True}:
        if len(kinds) > 1 and unc is not None and unc.described is not None:
            raise DatasetError(
                "the runs' UKF files mix described cars (axles_from: description) and others, "
                "and this model keeps a σ for each kind: calibrate each on its own "
                "(--car described, --car recorded)"
            )
        return False
    if unc is None or unc.fit_range is not None:
        raise DatasetError(
            "a σ for described car files is kept beside the model's own σ: "
            + (
                "calibrate that first, with true or identified car files"
                if unc is None
                else "this model's σ was fitted on one car's recordings, which read one file"
            )
        )
    return True


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="sideslip-calibrate",
        description=(
            "Fit a model's per-sample standard deviation on validation bags (never test "
            "ones): variance terms by likelihood on half the bags, a conformal scale on the "
            "other half; writes the model with it (docs/training.md, 'Intervals')."
        ),
    )
    p.add_argument("--model", required=True, help="a .safetensors or a shipped name")
    p.add_argument("--data", nargs="+", required=True, metavar="DIR", help="validation bags")
    p.add_argument("--out", required=True, type=Path, metavar="FILE.safetensors")
    p.add_argument("--coverage", type=float, default=0.95, help="share inside ±z·σ (0.95)")
    p.add_argument("--seed", type=int, default=0, help="which bags fit and which scale")
    p.add_argument("--topic-map", type=Path, metavar="FILE", help="see sideslip-train")
    p.add_argument(
        "--scale-only",
        action="store_true",
        help="keep the model's σ terms (its calibration on a fleet) and fit only their "
        "scale, on all of --data (e.g. one car's own recordings; on validation cars this "
        "did not bring coverage on the car's other drives nearer the asked share: "
        "docs/evaluation/intervals)",
    )
    add_mirror_average_argument(p, "calibrate on the errors of the network")
    add_car_files_arguments(p)
    p.add_argument("--force", action="store_true", help="replace --out")
    p.epilog = (
        "For a model that reads the UKF, runs whose car files were made from a description "
        "(--car described, or a file with axles_from: description) calibrate the σ the "
        "node publishes with such files; the model's σ for other files is kept. A mix of "
        "both kinds (--car mixed) calibrates a model's one σ, where it keeps no σ for "
        "described files."
    )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if not 0.5 <= args.coverage < 1.0:
            raise DatasetError(f"--coverage must be in [0.5, 1), got {args.coverage}")
        if args.out.exists() and not args.force:
            raise DatasetError(f"--out {args.out} exists; pass --force")
        path = resolve(args.model)
        model, meta = load_model(path)
        tensors, _ = read_artifact(path)
        topic_map = TopicMap.load(args.topic_map) if args.topic_map else None
        runs, report = load_runs(args.data, step_s=meta.dt_s, topic_map=topic_map)
        print(str(report), file=sys.stderr)
        if args.car == "given" and not (args.vehicle or args.observer_params):
            raise DatasetError("--car given needs --vehicle and/or --observer-params")
        car = {
            "vehicle": VehicleDescription.load(args.vehicle) if args.vehicle else None,
            "observer_params_file": str(args.observer_params) if args.observer_params else None,
            "car": args.car,
        }
        described = for_described_files(runs, meta, car)
        # The same network: the σ for the other kind of car file still holds.
        old = None if meta.uncertainty is None else Uncertainty.from_dict(meta.uncertainty)
        start = meta
        if described and old is not None and old.described is not None:
            # --scale-only rescales the σ for described files, not the model's own.
            start = replace(meta, uncertainty=old.described.to_dict())
        # σ for the estimate the node publishes with the same setting.
        mirror = mirror_average_on(args.mirror_average, meta.provenance)
        unc, figures = calibrate(
            runs,
            model,
            start,
            coverage=args.coverage,
            seed=args.seed,
            scale_only=args.scale_only,
            car={**car, "mirror_average": mirror},
        )
        figures = {**figures, "mirror_averaged": float(mirror)}
        if described:
            assert old is not None  # for_described_files checks it
            unc = replace(old, described=replace(unc, fit_range=None))
        elif old is not None:
            unc = replace(unc, described=old.described)
    except (
        DatasetError,
        ArtifactError,
        InitError,
        TopicMapError,
        OSError,
        VehicleDescriptionError,
    ) as err:
        print(f"sideslip-calibrate: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if described:
        print("calibrated the σ for car files made from a description (axles_from: "
              "description); the model's σ for other files is kept", file=sys.stderr)  # fmt: skip
    shown = unc.described if described and unc.described is not None else unc
    # The σ for other files keeps the record of its own calibration.
    suffix = "_described" if described else ""
    out_meta = replace(
        meta,
        uncertainty=unc.to_dict(),
        metrics={**meta.metrics, f"interval_calibration{suffix}": figures},
        provenance={**meta.provenance, f"calibrated{suffix}_on": [str(d) for d in args.data]},
    )
    write_artifact(args.out, tensors, out_meta, force=args.force)
    print(
        f"wrote {args.out}: σ² = {shown.scale:.3f}² · ("
        + " + ".join(f"{c:.3g}·{t}" for c, t in zip(shown.coefficients, TERMS, strict=True))
        + f"); {figures['coverage_scale_half']:.3f} of the scale half's samples inside "
        f"±{z_of(shown.coverage):.2f}σ; per run {figures['coverage_per_run_min']:.3f} (min) to "
        f"{figures['coverage_per_run_median']:.3f} (median), a constant σ: "
        f"{figures['constant_sigma_coverage_per_run_min']:.3f} to "
        f"{figures['constant_sigma_coverage_per_run_median']:.3f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
