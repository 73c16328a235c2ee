"""Scoring for ``sideslip-fit --bags``: every estimator on the recordings' test parts or
on ``--test-bags`` (the fitted and the shipped model, the UKF with the identified and the
described axles, the baselines), pooled into the card's tables. :mod:`.fit_bags` runs
the fit."""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final

from .cli_errors import CliError
from .fit_bags_card import Scored

IDENTIFIED_UKF: Final = "UKF (identified axles)"
DESCRIBED_UKF: Final = "UKF (described axles)"


def load_recordings(
    args: argparse.Namespace, bags: Sequence[str], **kwargs: Any
) -> tuple[list[Any], Any]:
    from sideslip_msgs_py.topic_map import TopicMap

    from .dataset import load_runs

    topic_map = TopicMap.load(args.topic_map) if args.topic_map else None
    return load_runs(list(bags), topic_map=topic_map, **kwargs)


def scored_traces(
    args: argparse.Namespace,
    bags: Sequence[str],
    fraction: float | None,
    models: Sequence[Path],
    ukf_file: Path | None,
    described_ukf: Path | None,
    runs: Sequence[Any] | None = None,
    mirror_average: bool | str = "auto",
) -> tuple[list[Any], list[str]]:
    """Every estimator's traces on each recording's test part (its last ``fraction``, as
    ``sideslip-train`` cut it; ``None``: the whole recording), resampled to the models'
    step, and the models' labels. ``mirror_average``: as the node's parameter; ``auto``
    (the node's default) averages the shipped start, which learnt from simulated runs
    alone, and not the model fitted to the recordings."""
    import numpy as np

    from sideslip_msgs_py.vehicle_description import VehicleDescription

    from .evaluate import Trace, evaluate_runs, model_label
    from .export import load_model
    from .filter_replay import physics_filter
    from .splits import split_in_time

    loaded = [load_model(m) for m in models]
    meta = loaded[0][1]
    labels = [f"{model_label(m)} ({p.stem})" for (_, m), p in zip(loaded, models, strict=True)]
    if runs is None:
        runs, _ = load_recordings(args, bags, step_s=meta.dt_s)
    tail = runs if fraction is None else split_in_time(runs, fraction, "test")[1]
    tail = [r for r in tail if len(r.samples) >= meta.window_steps]
    if not tail:
        where = "test bag" if fraction is None else "recording's test part"
        raise CliError(
            f"no {where} holds a full window of {meta.window_steps} samples: record longer"
            + ("" if fraction is None else " or raise --test-fraction")
        )
    measurable = ukf_file is not None
    traces = evaluate_runs(
        tail,
        [(label, net, m) for label, (net, m) in zip(labels, loaded, strict=True)],
        window_steps=meta.window_steps,
        dt_s=meta.dt_s,
        vehicle=VehicleDescription.load(args.vehicle) if measurable else None,
        observer_params_file=str(ukf_file) if measurable else None,
        car="given" if measurable else "recorded",
        filters={"ukf": str(ukf_file)} if measurable else None,
        mirror_average=mirror_average,
    )
    if measurable:
        # The kinematic baselines read the lateral velocity: in a recording that is the
        # reference itself, a sensor the car does not have.
        traces = [t for t in traces if not t.estimator.startswith("Kinematic")]
        traces = [
            dataclasses.replace(t, estimator=IDENTIFIED_UKF) if t.estimator == "UKF" else t
            for t in traces
        ]
    if described_ukf is not None:
        for run in tail:
            ref = run.samples.beta_rad()[meta.window_steps - 1 :]
            t = (np.arange(ref.size) + meta.window_steps - 1) * meta.dt_s
            est = physics_filter(run, "ukf", str(described_ukf), meta.window_steps)
            traces.append(Trace(run.name, DESCRIBED_UKF, t, est, ref, None))
    return traces, labels


def scored_table(traces: Sequence[Any], labels: Sequence[str], table: Path, title: str) -> Scored:
    """Pooled rows (the fitted model first, then what the node gives without the fit,
    then the rest) and the published 95 % interval's share of samples for the models
    with σ; writes the per-recording ``table``."""
    from .evaluate import interval_coverage, pooled
    from .evaluate_tables import table_markdown

    table.write_text(table_markdown(list(traces), title))
    rows = pooled(list(traces))
    order = [*labels, IDENTIFIED_UKF, DESCRIBED_UKF, *rows]
    rows = {name: rows[name] for name in dict.fromkeys(order) if name in rows}
    inside = {n: interval_coverage([t for t in traces if t.estimator == n]) for n in rows}
    return Scored(rows, {n: c for n, c in inside.items() if math.isfinite(c)}, table)


def pooled_json(scored: Scored) -> list[dict[str, Any]]:
    """The pooled rows as the summary's JSON: metrics in degrees, and the share inside
    ±1.96 σ (``coverage_95``) for the models that publish σ."""
    from .evaluate import metrics_json

    return [
        {
            "estimator": n,
            **metrics_json(m),
            **({"coverage_95": scored.inside[n]} if n in scored.inside else {}),
        }
        for n, m in scored.rows.items()
    ]
