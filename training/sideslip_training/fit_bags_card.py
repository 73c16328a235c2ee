"""The model card ``sideslip-fit --bags`` writes next to the fitted model (``OUT.md``).

Markdown only: every figure comes from :func:`.fit_bags.run`'s scoring and the training
run's ``metrics.json``; nothing here computes a metric.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sideslip_msgs_py.uncertainty import GENTLE_LATERAL_MPS2


@dataclass(frozen=True)
class Scored:
    """One test's pooled rows: estimator → metrics (MAE, RMSE, R² in degrees), the share
    of samples inside ±1.96 σ for the estimators that publish σ, and its per-recording
    table."""

    rows: dict[str, Any]
    inside: dict[str, float]
    table: Path


def model_card(
    args: argparse.Namespace,
    recipe_summary: str,
    fraction: float,
    found: Any,
    test_part: Scored,
    new_drives: Scored | None,
    train_metrics: dict[str, Any],
    seconds: float,
    uncertainty: dict[str, Any] | None = None,
) -> str:
    """The card: data, σ, deployment, the test part's table, the separate recordings'
    table (``--test-bags``) when given, and the limits. ``uncertainty``: the model's
    (its metadata's), to state where its σ holds."""
    ukf = args.out.with_suffix(".ukf.yaml")
    car_files = (
        f" -p pso_lstm.vehicle_file:={args.vehicle} -p pso_lstm.observer_params_file:={ukf}"
        if found is not None
        else ""
    )
    axles = (
        f"\n\nThe UKF's axles, identified from the same part (`{ukf}`): cornering stiffness "
        f"front ×{found.stiffness_ratio_front:.3f}, rear ×{found.stiffness_ratio_rear:.3f} "
        f"of the description's, from {found.points} quasi-steady points. The node's `ukf` "
        "back-end and this model both read that file."
        if found is not None
        else ""
    )
    averaged = (train_metrics.get("validation_mirror_averaged") or {}).get("start")
    kept = (
        "\n\n**No epoch of fine-tuning beat the shipped model on validation"
        + (" (neither run alone nor averaged with its mirror image)" if averaged else "")
        + ": this file holds the shipped weights, and the node runs it as it ran the "
        "shipped model.**"
        if train_metrics.get("kept_start_weights")
        else ""
    )
    topic_map = f" --topic-map {args.topic_map}" if args.topic_map else ""
    test_bags = f" --test-bags {' '.join(args.test_bags)}" if args.test_bags else ""
    return f"""# Model card: {args.out.name}

Fitted by `sideslip-fit --vehicle {args.vehicle} --bags {" ".join(args.bags)}{topic_map}
--features {args.features} --profile {args.profile}{test_bags}` in {seconds:.0f} s.

## Data

The car's own recordings, each split in time: the first {1 - fraction:.0%} for
identification and fine-tuning ({recipe_summary}, `--split time`: {_choice(train_metrics)}),
the last {fraction:.0%} for the test below and nothing
else.{axles}{kept}{_sigma(train_metrics, uncertainty)}

## Deploy

`-p pso_lstm.model_file:={args.out}{car_files}`

## Result on the test part (pooled over the recordings, degrees)

{_table(test_part)}

Per recording: `{test_part.table}`. The shipped model's row is what the node gives
without this fit{_shipped_note(found)}.
{_new_drives(new_drives)}
## Limits

{_limits(args, found, topic_map, new_drives is not None)}
"""


def _choice(train_metrics: dict[str, Any]) -> str:
    """How the fine-tune's epoch count was chosen: on the stretch before the test part,
    or out of fold over the whole part before it (``--folds``)."""
    cv = train_metrics.get("cross_validation")
    if not cv:
        return "the validation part is the stretch before the test"
    epochs = cv["epochs"]
    plural = "s" * (epochs != 1)
    chosen = (
        "keeping the start" if cv["kept_start"] else f"{epochs} epoch{plural}, refit on all of it"
    )
    return (
        f"the epoch count chosen by {cv['folds']}-fold cross-validation over the whole "
        f"part, each recording cut into {cv['folds']} blocks in time: {chosen} (pooled "
        f"out-of-fold MAE {cv['pooled_mae_deg']:.4f}° against the start's "
        f"{cv['start_pooled_mae_deg']:.4f}°)"
    )


def _table(scored: Scored) -> str:
    rows = "\n".join(
        f"| {name} | {m.mae:.4f} | {m.rmse:.4f} | {m.r2:.3f} | "
        f"{f'{scored.inside[name]:.1%}' if name in scored.inside else '—'} | {m.n} |"
        for name, m in scored.rows.items()
        if math.isfinite(m.mae)
    )
    return (
        "| estimator | MAE | RMSE | R² | inside ±1.96 σ | samples |\n"
        "|---|---|---|---|---|---|\n" + rows
    )


NARROW_SHARE = 0.90
"""Below this share of the separate recordings inside ±1.96 σ the card warns: the σ set
on the fit's own drives is too narrow for them."""


GENTLE_MPS2 = GENTLE_LATERAL_MPS2
"""Recordings whose lateral range (:class:`~sideslip_msgs_py.uncertainty.FitRange`) stays
under this [m/s², about 0.5 g] get a warning: on validation cars fitted on driving under
4 m/s² the fitted model erred more than the shipped one on harder drives in 4 of 8
(docs/evaluation/fit-bags, "Gentle recordings"); the 6.9–8.7 m/s² of varied driving
never triggers it."""


def gentle_recordings(uncertainty: dict[str, Any] | None) -> float | None:
    """The recordings' lateral range [m/s²] when under :data:`GENTLE_MPS2`, else None."""
    from sideslip_msgs_py.uncertainty import Uncertainty

    fit = None if uncertainty is None else Uncertainty.from_dict(uncertainty).fit_range
    if fit is None or fit.lateral_acceleration_mps2 >= GENTLE_MPS2:
        return None
    return fit.lateral_acceleration_mps2


def fitted_share(scored: Scored) -> float | None:
    """The fitted model's (first row's) share inside ±1.96 σ, None without σ."""
    return scored.inside.get(next(iter(scored.rows)))


def narrow_interval(scored: Scored) -> float | None:
    """The fitted model's share inside ±1.96 σ when below :data:`NARROW_SHARE`, else
    None."""
    share = fitted_share(scored)
    return share if share is not None and share < NARROW_SHARE else None


WIDE_SHARE = 0.99
"""From this share of the separate recordings inside ±1.96 σ on, the card notes that σ
is wider than those drives need (a fifth of the misses a 95 % interval should have). On
the held-out six, fits of 7.5 minutes held 0.955–0.984 on their own drives' test part
and 0.999–1.000 on other drives (docs/evaluation/intervals, "fitted half way back")."""


def wide_interval(scored: Scored) -> float | None:
    """The fitted model's share inside ±1.96 σ when at or above :data:`WIDE_SHARE`, else
    None."""
    share = fitted_share(scored)
    return share if share is not None and share >= WIDE_SHARE else None


def _interval_note(scored: Scored) -> str:
    share = narrow_interval(scored)
    if share is not None:
        return (
            f"\n\n**Only {share:.1%} of these samples lie inside the fitted model's ±1.96 σ: "
            "its σ, set on the fit's own drives, is too narrow for these. Fit again with "
            "recordings that hold this kind of driving.**"
        )
    share = wide_interval(scored)
    if share is not None:
        # Wide is the safe side, but a consumer that weights β̂ by σ trusts it less than
        # these drives warrant: say so rather than let the table imply a 95 % interval.
        return (
            f"\n\n{share:.1%} of these samples lie inside the fitted model's ±1.96 σ: on "
            "these drives σ is wider than a 95 % interval needs. It was set on the fit's "
            "own drives, which erred more than these; a stability controller that weights "
            "β̂ by σ will trust it less than these drives warrant."
        )
    return ""


def _new_drives(scored: Scored | None) -> str:
    if scored is None:
        return ""
    warning = _interval_note(scored)
    return f"""
## Result on the separate recordings (`--test-bags`, whole, degrees)

Never used to identify the axles, to train, to choose an epoch or to set σ: the check
on drives the fit has not seen.

{_table(scored)}{warning}

Per recording: `{scored.table}`.
"""


def _sigma(train_metrics: dict[str, Any], stored: dict[str, Any] | None) -> str:
    from sideslip_msgs_py.uncertainty import Uncertainty

    from .train_intervals import OUTSIDE_FACTOR

    calibration = train_metrics.get("interval_calibration")
    if not calibration:
        return "\n\nIt carries no per-sample σ: the node publishes its validation RMSE²."
    terms = (
        "the shipped model's σ terms, their scale"
        if calibration["scale_only"]
        else "σ terms and scale, on halves of the recordings,"
    )
    text = (
        f"\n\nIts σ (published in `/sideslip/twist`): {terms} fitted on the validation "
        "stretch with the model chosen before the refit, which had not trained on it "
        f"({calibration['coverage_scale_half']:.1%} of that stretch inside ±1.96 σ)."
    )
    fit = None if stored is None else Uncertainty.from_dict(stored).fit_range
    if fit is not None:
        text += (
            f" That scale holds for driving like the recordings' (|a_y| ≤ "
            f"{fit.lateral_acceleration_mps2:.2f} m/s², |β̇| ≤ {fit.beta_rate_radps:.3f} rad/s); "
            + (
                "while the input window reaches beyond, the node publishes the shipped "
                "model's estimate and σ instead (`pso_lstm.beyond_fit_range` `auto` for "
                "recordings this gentle, as the tables below score it), or with "
                "`beyond_fit_range:=model` this model's, σ "
                if fit.gentle
                else "while the input window reaches beyond, σ "
            )
            + f"at scale {fit.outside_scale:.2f} ({OUTSIDE_FACTOR:g} × the shipped model's) "
            "where that is wider."
        )
    gentle = gentle_recordings(stored)
    if gentle is not None:
        text += (
            f"\n\n**The recordings stay under {math.ceil(gentle * 10) / 10:.1f} m/s² of "
            "lateral acceleration.** "
            "Beyond that the fine-tuned network extrapolates: on validation cars fitted on "
            "driving under 4 m/s² it erred more than the shipped model on their harder "
            "drives in 4 of 8 (mean MAE 0.071° against 0.055°; with the node's fall-back "
            "to the shipped model beyond the recordings 0.060°). On the six held-out cars "
            "fitted the same way, with the fall-back, 0.053° against the shipped model's "
            "0.054° (better on 3 of 6), and σ too narrow on low-friction roads (70–87 % "
            "inside at μ 0.4 on four cars; these figures from the start shipped before "
            "2026-12-03; docs/evaluation/fit-bags). "
            "Record driving nearer the limit (a skid pad, a closed course) and fit again, "
            "or keep the shipped model."
        )
    return text


# Measured on the simulated held-out cars (docs/evaluation/fit-bags, 2026-12-03; the
# ensemble start: docs/evaluation/held-out-curve and docs/models/fleet_ukf_ensemble/
# finetune-lr-validation.json, 2026-12-05; run alone against the averaged start:
# docs/evaluation/fit-bags/handover-validation.json, 2026-12-06): the
# own-drive test part favours a fit that other drives of the same car do not.
OWN_DRIVES_CAUTION = (
    "On six simulated held-out cars, plain fits from the shipped start beat it on their own "
    "test part (0.053° against 0.060°) but not on other drives of the cars (0.031° against "
    "the shipped model's 0.028° with the identified `ukf` file); kept half way from the "
    "start (`--interpolate 0.5`) they beat it there by 6 % (0.0265°, worse on 1 of 6); from "
    "`fleet_ukf_ensemble` with 5 minutes of driving (a quarter of the way) by 3.5 %, on all 6, "
    "but on eight validation cars such fits beat the start by only 3 % and were 27 % worse "
    "on one. Run alone, as the node runs a fit to recordings, fits on six validation cars "
    "were level with the shipped model averaged with its mirror image, as the node runs "
    "it (0.0292° against 0.0293°, on other drives both ways round; worse on 2 of 6): before "
    "deploying, compare both on a recording the fit never saw, driven both ways. "
)


def _limits(args: argparse.Namespace, found: Any, topic_map: str, new_drives: bool) -> str:
    covered = (
        "Fitted on these recordings only: other roads, tyres, loads and sensor mountings "
        "than they hold are not covered by the tests. "
    )
    if found is not None:
        # Only the measurable fit (a start model run with the identified file) was measured.
        covered += OWN_DRIVES_CAUTION
    if new_drives:
        # σ is set on the validation stretch of the same drives as the training: a
        # manoeuvre those drives lack is where it is most likely too narrow.
        return covered + (
            "Where the separate recordings' share inside ±1.96 σ is well below 95 %, they "
            "hold driving the fit's recordings lack: record more of it and fit again (on "
            "simulated held-out cars a step steer at the friction limit that the own "
            "driving lacked put 17 % of its samples inside; docs/evaluation/intervals)."
        )
    return covered + (
        "A test part from the same drives as the training is easier than a new drive; keep "
        "a separate recording for a final check (`--test-bags`, or `sideslip-evaluate "
        f"--model {args.out}{topic_map}{_eval_files(args, found)}`)."
    )


def _eval_files(args: argparse.Namespace, found: Any) -> str:
    if found is None:
        return " --data NEW_BAGS"
    ukf = args.out.with_suffix(".ukf.yaml")
    return f" --data NEW_BAGS --vehicle {args.vehicle} --observer-params {ukf} --car given"


def _shipped_note(found: Any) -> str:
    if found is None:
        return ""
    return (
        " (with the identified axle file). The kinematic baselines are left out: they read "
        "the lateral velocity, which in these recordings is the reference itself"
    )
