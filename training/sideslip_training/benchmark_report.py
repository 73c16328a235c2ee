"""The README of ``sideslip-benchmark``: markdown tables of the scores, verdicts, and the text
around them (what was run, on which cars, how it is scored)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Final

from .benchmark_data import expected_run_count
from .benchmark_estimators import (
    KINEMATIC_MEAN,
    KINEMATIC_RAW,
    PHYSICS_BACKENDS,
    SMOOTHING_STEPS,
    ZERO,
    Network,
    PhysicsFilter,
)
from .benchmark_scores import (
    KINEMATIC_RATIO_LIMIT,
    MEASURABLE_MAE_LIMIT_DEG,
    PHYSICS_RATIO_LIMIT,
    Summary,
    best_physics_mae,
    verdicts,
)


def _fmt(value: float, digits: int = 3) -> str:
    return f"{value:.{digits}f}" if math.isfinite(value) else "n/a"


def _row_markdown(cells: Sequence[str], values: Sequence[float], best: Callable | None) -> str:
    """A table row; the best value (``best`` = min or max over the finite ones) in bold."""
    finite = [v for v in values if math.isfinite(v)]
    top = best(finite) if best and finite else None
    shown = [f"**{_fmt(v)}**" if top is not None and v == top else _fmt(v) for v in values]
    return "| " + " | ".join([*cells, *shown]) + " |"


METRICS: Final = (
    ("mae_deg", "MAE [deg]", min),
    ("rmse_deg", "RMSE [deg]", min),
    ("r2", "R²", max),
    ("max_abs_deg", "max |error| [deg]", min),
)


def cell_table(summary: Summary, metric: str, best: Callable) -> str:
    """Car × μ rows, estimator columns, and the mean over cells."""
    head = ["car", "μ", *summary.labels]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for (vehicle, mu), scores in summary.cells.items():
        lines.append(
            _row_markdown(
                [vehicle, f"{mu:.1f}"],
                [getattr(scores[lab], metric) for lab in summary.labels],
                best,
            )
        )
    lines.append(
        _row_markdown(
            ["**mean over cells**", ""],
            [summary.overall[lab][metric] for lab in summary.labels],
            best,
        )
    )
    return "\n".join(lines)


def vehicle_table(summary: Summary) -> str:
    head = ["car", *summary.labels]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for vehicle, scores in summary.vehicles.items():
        lines.append(_row_markdown([vehicle], [scores[lab].mae_deg for lab in summary.labels], min))
    return "\n".join(lines)


def run_table(summary: Summary) -> str:
    head = ["run", "μ", "spin onset [s]", "samples", *summary.labels]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in summary.runs:
        onset = "—" if r.run.spin_onset_s is None else f"{r.run.spin_onset_s:.2f}"
        lines.append(
            _row_markdown(
                [
                    f"{r.run.vehicle_name} {r.run.kind}",
                    f"{r.run.mu:.1f}",
                    onset,
                    str(int(r.scored.sum())),
                ],
                [r.score(lab).mae_deg for lab in summary.labels],
                min,
            )
        )
    return "\n".join(lines)


def _verdict_word(passed: bool | None) -> str:
    return {True: "PASS", False: "FAIL", None: "UNDECIDED"}[passed]


def verdict_markdown(summary: Summary, networks: Sequence[Network]) -> str:
    if not networks:
        return "No network was scored (`--no-default-models` and no `--model`): nothing to pass."
    vs = verdicts(summary, networks)
    out = [
        f"Per network: on how many runs its MAE is higher than the {KINEMATIC_MEAN} "
        "baseline's, and the mean over runs of its MAE over the baseline's.",
        "",
        f"| network | features | runs worse than {KINEMATIC_MEAN} | mean MAE ratio to it |",
        "|---|---|---|---|",
    ]
    n_runs = len(summary.runs)
    for v in vs:
        out.append(
            f"| {v.network} | {v.features} | {len(v.runs_worse_than_kinematic)} of "
            f"{n_runs} | {_fmt(v.mean_ratio_to_kinematic)} |"
        )
    measurable = [v for v in vs if v.features == "measurable"]
    if measurable:
        physics = [lab for lab in PHYSICS_BACKENDS if lab in summary.labels]
        out += [
            "",
            "Networks without Y_v against the better physics filter "
            f"(min of {', '.join(physics) or 'none ran'}), per car, MAE pooled over μ: the "
            "ratio of the network's MAE to the filter's.",
            "",
            "| car | better filter | its MAE [deg] | "
            + " | ".join(v.network for v in measurable)
            + " |",
            "|" + "---|" * (3 + len(measurable)),
        ]
        for vehicle in summary.vehicles:
            best = best_physics_mae(summary, vehicle)
            which = next(
                (lab for lab in physics if summary.vehicles[vehicle][lab].mae_deg == best), "—"
            )
            ratios = [_fmt(v.ratio_to_best_physics.get(vehicle, math.nan)) for v in measurable]
            out.append(f"| {vehicle} | {which} | {_fmt(best)} | " + " | ".join(ratios) + " |")
    complete = n_runs == expected_run_count()
    out += [
        "",
        "Verdicts against issue 8"
        + (
            ""
            if complete
            else f" (on {n_runs} of the {expected_run_count()} runs: not the full benchmark)"
        )
        + ":",
        "",
    ]
    for v in vs:
        checks = "; ".join(
            f"{c.criterion}: {c.measured} → {_verdict_word(c.passed)}" for c in v.checks
        )
        out.append(f"- **{v.network}** ({v.features}): **{_verdict_word(v.passed)}**. {checks}.")
    return "\n".join(out)


def readme_markdown(
    summary: Summary,
    networks: Sequence[Network],
    filters: Sequence[PhysicsFilter],
    notes: Sequence[str],
    context: Mapping[str, Any],
    figures: Sequence[Path],
) -> str:
    machine = context["machine"]
    n_runs = len(summary.runs)
    cars = {r.run.vehicle_name: r.run.vehicle for r in summary.runs}
    noise = sorted({r.run.noise for r in summary.runs})
    spun = [r for r in summary.runs if r.run.spin_onset_s is not None]
    left_out = sum(int(r.scored.size - r.scored.sum()) for r in summary.runs)
    window = context["window_steps"]
    both_ways = bool(context.get("both_ways"))
    full_runs = expected_run_count() * (2 if both_ways else 1)
    lines = [
        "# Held-out benchmark",
        "",
        "Six cars that no training set, PSO run or filter tuning ever contains "
        "(`sideslip_sim.held_out`; every training preset refuses them by parameter digest), "
        "each at road μ = 1.0, 0.7 and 0.4, through the Table 4 scenarios (scen1–scen4), a "
        "step steer and a sine sweep (80 km/h, 10 s), with sensor noise "
        f"{', '.join(f'`{n}`' for n in noise)}: {n_runs} runs"
        + ("" if n_runs == full_runs else f" of the {full_runs} of the full benchmark")
        + (
            ": each run and its mirror image, the same drive turned the other way round "
            "(`--both-ways`), in the same cell"
            if both_ways
            else ""
        )
        + ". "
        + mirror_sentence(context)
        + "Steering amplitudes are each car's own (a steady-state lateral acceleration of "
        "0.85·μ·g at the run's speed). These cars are scored here, once per model, and never "
        "trained or tuned on.",
        "",
        "Made by",
        "",
        f"    {context['command']}",
        "",
        f"at commit `{machine['commit']}`"
        + (" (with uncommitted changes)" if machine.get("uncommitted_changes") else "")
        + f", {context['when']}, on {machine['cpu']} ({machine['cpu_count']} CPUs, "
        f"{context['jobs']} job(s)): {context['wall_s']:.0f} s. Every number below is in "
        "`results.json`.",
        "",
        "## The cars",
        "",
        "| car | what it is | parameters |",
        "|---|---|---|",
        *(
            f"| {name} | {v.get('description', '')} | [{name}.yaml](vehicles/{name}.yaml) |"
            for name, v in cars.items()
        ),
        "",
        "## What is scored",
        "",
        f"β̂ − β in degrees against the simulator's exact β, on the samples of each run with a "
        f"full {window}-step window behind them (index ≥ {window - 1}, as the networks see "
        "them); every estimator on the same samples"
        + (
            f" ({left_out} sample(s) where some estimator gave no estimate are left out for all; "
            "`without_estimate` in results.json)"
            if left_out
            else ""
        )
        + ". "
        "A cell (car × μ) pools the samples of its runs; the per-car table pools its three "
        "cells; *mean over cells* is the plain mean of the cells' figures. Bold: the best "
        "value in a row.",
        "",
        f"- **{ZERO}**: the floor.",
        f"- **{KINEMATIC_RAW}**, **{KINEMATIC_MEAN}**: atan2(Y_v, X_v), as measured and as "
        f"the causal mean of the last {SMOOTHING_STEPS} samples: the baseline of any network "
        "that reads Y_v (`paper` features).",
    ]
    tuned = context.get("physics_params_file")
    for f in filters:
        what = (
            "linear single-track Kalman filter"
            if f.backend == "single_track"
            else "unscented Kalman filter on a nonlinear single-track model with Magic "
            "Formula axles"
        )
        lines.append(f"- **{f.label}**: the estimator's `{f.backend}` back-end ({what}).")
    if filters:
        lines.append(
            "  The physics filters run sample by sample through the estimator core as the "
            "node runs them, with each car's true nominal parameters ([physics/](physics/)), "
            + (f"the noise settings of `{tuned}`" if tuned else "the back-ends' default noise")
            + ", and the node's input checks with the steering limit `limits.stl_m` raised to "
            "1.5 × the car's STL at full lock (the default 0.5 m is below these cars' full "
            "lock, which their path-following runs reach)."
        )
    for n in networks:
        lines.append(
            f"- **{n.label}**: `{n.path.name}` ({n.meta.architecture}, {n.meta.hidden_units} "
            f"units, features {', '.join(n.meta.features)}), trained on data "
            f"`{n.meta.training_data_digest[:12]}`."
        )
    for note in notes:
        lines.append(f"- Note: {note}.")
    if spun:
        lines += [
            "",
            f"{len(spun)} run(s) spin (|β| beyond the generator's limit; onset in the per-run "
            "table); they are scored up to the spin onset, as training uses them.",
        ]
    for key, title, best in METRICS:
        lines += ["", f"## {title} per car × μ", "", cell_table(summary, key, best)]
    lines += ["", "## MAE [deg] per car (pooled over μ)", "", vehicle_table(summary)]
    lines += [
        "",
        "## Pass / fail (issue 8)",
        "",
        f"- Networks without Y_v (`measurable`): mean MAE over cells ≤ "
        f"{MEASURABLE_MAE_LIMIT_DEG:.2f}°, and on every car at most "
        f"{PHYSICS_RATIO_LIMIT:g}× the MAE of the better physics filter "
        f"({' or '.join(PHYSICS_BACKENDS)}).",
        f"- Networks with Y_v (`paper`): on no run a higher MAE than {KINEMATIC_MEAN}, "
        f"and at most {KINEMATIC_RATIO_LIMIT:g}× its MAE on average (mean over runs of "
        "the per-run ratio).",
        "",
        verdict_markdown(summary, networks),
    ]
    lines += ["", "## Figures", ""]
    lines += [f"![{p.stem}](figures/{p.name})" for p in figures]
    lines += ["", "## MAE [deg] per run", "", run_table(summary), ""]
    return "\n".join(lines)


def mirror_sentence(context: Mapping[str, Any]) -> str:
    """Which networks the report averaged with their mirror image (``--mirror-average``,
    the node's ``pso_lstm.mirror_average``), as a sentence ending in a space; reports
    written before the per-network record said only yes or no."""
    averaged = context.get("mirror_averaged")
    if averaged is None:  # a bool then
        averaged_all = context.get("mirror_average") is True
        return (
            "Every network is averaged with its own mirror image (`--mirror-average`, the "
            "node's `pso_lstm.mirror_average`). "
            if averaged_all
            else ""
        )
    on = [label for label, yes in averaged.items() if yes]
    setting = context.get("mirror_average", "auto")
    if not on:
        return f"No network is averaged with its mirror image (`--mirror-average {setting}`). "
    how = f"(`--mirror-average {setting}`, as the node's `pso_lstm.mirror_average`" + (
        ": each network whose file records that it learnt from simulated runs only)"
        if setting == "auto"
        else ")"
    )
    if len(on) == len(averaged):
        return f"Every network is averaged with its own mirror image {how}. "
    if len(on) == 1:
        return f"{on[0]} is averaged with its own mirror image {how}. "
    return f"{', '.join(on[:-1])} and {on[-1]} are averaged with their own mirror images {how}. "
