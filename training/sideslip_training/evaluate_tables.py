"""Tables of :func:`.evaluate.evaluate_runs`' traces: markdown (the paper's Table 5/6
layout, with the per-bag mean, the pooled row and the 95 % interval's coverage) and CSV.
Formatting only; the metrics come from :mod:`.evaluate`."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence

import numpy as np

from .evaluate import Metrics, Trace, interval_coverage, pooled


def _num(x: float, spec: str) -> str:
    """``x`` formatted, or "n/a" when it is not finite (no NaN in a table)."""
    return format(x, spec) if math.isfinite(x) else "n/a"


def _rows(traces: Sequence[Trace]) -> list[tuple[str, str, Metrics]]:
    return [(t.scenario, t.estimator, t.metrics) for t in traces]


def table_markdown(traces: Sequence[Trace], title: str = "") -> str:
    """Table 5/6 layout: one block per scenario, one row per estimator, plus the mean."""
    out = io.StringIO()
    if title:
        out.write(f"{title}\n\n")
    out.write("| Scenario | Model | MAE [deg] | ME [deg] | RMSE [deg] | R² |\n")
    out.write("|---|---|---|---|---|---|\n")
    last = None
    rows = _rows(traces)
    for scen, name, m in rows:
        label = scen if scen != last else ""
        last = scen
        out.write(
            f"| {label} | {name} | {_num(m.mae, '.3f')} | {_num(m.me, '+.3f')} | "
            f"{_num(m.rmse, '.3f')} | {_num(m.r2, '.3f')} |\n"
        )
    for name in dict.fromkeys(t.estimator for t in traces):
        ms = [t.metrics for t in traces if t.estimator == name]
        out.write(
            f"| mean | {name} | {_mean(ms, 'mae', '.3f')} | {_mean(ms, 'me', '+.3f')} | "
            f"{_mean(ms, 'rmse', '.3f')} | {_mean(ms, 'r2', '.3f')} |\n"
        )
    for name, m in pooled(traces).items():
        out.write(
            f"| pooled | {name} | {_num(m.mae, '.3f')} | {_num(m.me, '+.3f')} | "
            f"{_num(m.rmse, '.3f')} | {_num(m.r2, '.3f')} |\n"
        )
    out.write(
        "\n*mean*: the average of the per-bag figures (each bag counts once); *pooled*: "
        "over all samples of all bags (each sample counts once).\n"
    )
    with_sigma = [n for n in dict.fromkeys(t.estimator for t in traces) if _has_sigma(traces, n)]
    if with_sigma:
        out.write("\nShare of samples inside the published 95 % interval (β̂ ± 1.96 σ):\n\n")
        out.write("| Scenario | " + " | ".join(with_sigma) + " |\n")
        out.write("|---|" + "---|" * len(with_sigma) + "\n")
        for scen in dict.fromkeys(t.scenario for t in traces):
            cells = [
                interval_coverage([t for t in traces if t.scenario == scen and t.estimator == n])
                for n in with_sigma
            ]
            out.write(f"| {scen} | " + " | ".join(_num(c, ".3f") for c in cells) + " |\n")
        pooled_cov = [
            interval_coverage([t for t in traces if t.estimator == n]) for n in with_sigma
        ]
        out.write("| pooled | " + " | ".join(_num(c, ".3f") for c in pooled_cov) + " |\n")
    excluded = {name: 0 for _, name, _ in rows}
    for _, name, m in rows:
        excluded[name] += m.excluded
    notes = [f"{name}: {n}" for name, n in excluded.items() if n]
    if notes:
        out.write(
            "\nSamples left out (estimate or reference not finite, e.g. a filter below its "
            "speed, a non-finite sample in the bag, or the reference under 1 m/s, where β "
            f"is no target): {'; '.join(notes)}.\n"
        )
    return out.getvalue()


def _has_sigma(traces: Sequence[Trace], estimator: str) -> bool:
    return any(t.sigma_rad is not None for t in traces if t.estimator == estimator)


def _mean(ms: Sequence[Metrics], field: str, spec: str) -> str:
    """Mean of a metric over runs, leaving out runs where it is undefined (R² of a run
    whose β is constant, any metric of a run with no finite sample)."""
    values = [getattr(m, field) for m in ms if math.isfinite(getattr(m, field))]
    return format(float(np.mean(values)), spec) if values else "n/a"


def table_csv(traces: Sequence[Trace]) -> str:
    out = io.StringIO()
    writer = csv.writer(out)
    writer.writerow(
        ["scenario", "model", "mae_deg", "me_deg", "rmse_deg", "r2", "samples", "excluded"]
    )
    rows = [*_rows(traces), *(("pooled", n, m) for n, m in pooled(traces).items())]
    for scen, name, m in rows:
        writer.writerow(
            [scen, name] + [_num(x, ".6f") for x in (m.mae, m.me, m.rmse, m.r2)] + [m.n, m.excluded]
        )
    return out.getvalue()
