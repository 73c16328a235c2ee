"""``sideslip-fit --bags``: a model fitted to the car's own labelled recordings.

The description path (:mod:`.fit`) simulates cars like the user's; a user who has
recorded the car with a reference β (an INS, an optical sensor) has better data than any
simulation. One command then does what docs/training.md's "Axles from the car's own
recordings" does in two:

1. split every recording in time: its last ``--test-fraction`` is the test part, never
   used for anything but the final table (the same cut ``sideslip-train --split time
   --test-fraction`` makes);
2. ``measurable`` features: identify the UKF's axle stiffness from the rest
   (:func:`sideslip_sim.axle_identification.identify_axles`, starting from the
   description's car) and write that ``ukf`` file next to the model (``OUT.ukf.yaml``);
3. fine-tune the shipped fleet model on the same part (``sideslip-train --init``;
   ``measurable``: with the description and the identified file as the node is given
   them, ``--car given``);
4. score on the test part: the fitted model, the shipped model as it is (zero-shot,
   with the identified file), the UKF with the identified and with the described file,
   and the baselines; the same, whole, on ``--test-bags`` (other drives of the car, never
   used for anything else) when given; then the model card (``OUT.md``,
   :mod:`.fit_bags_card`).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from .cli_errors import CliError
from .fit_bags_card import Scored, gentle_recordings, model_card, narrow_interval
from .weight_interpolation import check_alpha

IDENTIFIED_UKF: Final = "UKF (identified axles)"
DESCRIBED_UKF: Final = "UKF (described axles)"
DEFAULT_TEST_FRACTION: Final = 0.3
"""The share of every recording kept for the test (the issue's 70/30 split in time)."""
DEFAULT_REHEARSAL_RUNS: Final = 0
"""Simulated runs of cars like the described one trained beside the recordings
(``--rehearse``)."""
DEFAULT_INTERPOLATION: Final = 0.5
"""The fitted weights kept half way from the start model's (``sideslip-train
--interpolate``): chosen on validation cars' other drives (docs/evaluation/fit-bags,
"Half way back to the start")."""
REHEARSAL_SEED: Final = 50_000
"""Added to ``--seed`` for the rehearsal's cars and runs: other cars than a description
fit's (``sideslip-fit`` without ``--bags``) with the same seed."""


@dataclass(frozen=True)
class BagRecipe:
    """How ``sideslip-train`` fine-tunes on the recordings."""

    train_args: tuple[str, ...]
    summary: str


BAG_RECIPES: Final = {
    # Measured on the six held-out cars with 5 minutes each (docs/evaluation/
    # held-out-curve, "the user's path"): ~1.5 min per training on 2 cores, 34 % better
    # than the same recipe from scratch on average, never worse than the shipped model.
    "quick": BagRecipe(
        ("--profile", "quick", "--stride", "10", "--mirror", "no"),
        "sideslip-train --profile quick --stride 10 --mirror no",
    ),
    # sideslip-train's small-data defaults (every window, runs mirrored left-right below
    # 1 M samples): 20 times the windows; on one validation car 1977 s against 266 s,
    # test-part MAE 0.0192 against 0.0244 (docs/evaluation/fit-bags).
    "thorough": BagRecipe(
        ("--profile", "quick"),
        "sideslip-train --profile quick (small-data defaults: stride 1, mirrored runs)",
    ),
}


def add_bag_arguments(p: argparse.ArgumentParser) -> None:
    """The options of the recordings path."""
    p.add_argument(
        "--bags",
        nargs="+",
        metavar="BAG",
        help="fit to the car's own recordings with a reference β (bags or folders) instead "
        "of simulating cars like it: identify the UKF's axles (measurable), fine-tune, "
        "test on each recording's last --test-fraction",
    )
    p.add_argument(
        "--topic-map",
        type=Path,
        metavar="FILE",
        help="with --bags: read bags (and --test-bags) recorded with other topics "
        "(docs/topic-maps.md)",
    )
    p.add_argument(
        "--test-fraction",
        type=float,
        default=None,
        help=f"with --bags: the last share of every recording kept for the test "
        f"(default {DEFAULT_TEST_FRACTION:g})",
    )
    p.add_argument(
        "--rehearse",
        type=int,
        metavar="RUNS",
        default=None,
        help="with --bags: simulated runs (fleet manoeuvres up to the limit, μ 0.3-1.0) of "
        "cars like the description's, trained beside the recordings but never validated, "
        "tested or calibrated on, so that the fit keeps what the shipped model knew "
        f"beyond the recordings (default {DEFAULT_REHEARSAL_RUNS}; 0: none; about 9 s "
        "of driving each; docs/evaluation/fit-bags, 'Rehearsal')",
    )
    p.add_argument(
        "--interpolate",
        type=float,
        metavar="ALPHA",
        default=None,
        help="with --bags: keep the start model's weights moved this share of the way to "
        f"the fine-tuned ones (default {DEFAULT_INTERPOLATION:g}: better on other drives "
        "than the plain fine-tuning (1) and the start (0) on validation cars; "
        "docs/evaluation/fit-bags)",
    )
    p.add_argument(
        "--test-bags",
        nargs="+",
        metavar="BAG",
        help="with --bags: other recordings of the car (bags or folders; other roads and "
        "manoeuvres), scored whole after the fit and never used to identify, train, "
        "choose or calibrate: the card's check on drives the fit has not seen",
    )


def check_bag_arguments(args: argparse.Namespace) -> float:
    """Refuse options that do not go together; the test fraction to use."""
    if args.bags is None:
        for name in ("topic_map", "test_fraction", "test_bags", "rehearse", "interpolate"):
            if getattr(args, name) is not None:
                raise CliError(f"--{name.replace('_', '-')} needs --bags")
        return 0.0
    for name in ("cars", "test_runs"):
        if getattr(args, name) is not None:
            raise CliError(f"--{name.replace('_', '-')} is for simulated fits, not with --bags")
    if args.rehearse is not None and args.rehearse < 0:
        raise CliError(f"--rehearse must be >= 0 runs, got {args.rehearse}")
    if args.interpolate is not None:
        try:
            check_alpha(args.interpolate)
        except ValueError as err:
            raise CliError(str(err)) from None
    fraction = DEFAULT_TEST_FRACTION if args.test_fraction is None else args.test_fraction
    if not (0.0 < fraction < 1.0 and math.isfinite(fraction)):
        raise CliError(f"--test-fraction must be in (0, 1), got {args.test_fraction}")
    return fraction


def _load(args: argparse.Namespace, bags: Sequence[str], **kwargs: Any) -> tuple[list[Any], Any]:
    from sideslip_msgs_py.topic_map import TopicMap

    from .dataset import load_runs

    topic_map = TopicMap.load(args.topic_map) if args.topic_map else None
    return load_runs(list(bags), topic_map=topic_map, **kwargs)


def split_recordings(
    args: argparse.Namespace, fraction: float, window_s: float, measurable: bool, log: Callable
) -> list[Any]:
    """Each recording's part before its test part, at the recordings' own rate.

    Raises CliError, before anything is trained, when no recording's test part holds a
    full window of ``window_s``."""
    from .identify_axles import CHANNELS
    from .splits import split_in_time

    runs, report = _load(args, args.bags, **({"channels": CHANNELS} if measurable else {}))
    log(str(report))
    head, tail = split_in_time(runs, fraction, "test")
    longest = max((r.samples.stamp_ns[-1] - r.samples.stamp_ns[0]) * 1e-9 for r in tail)
    if longest < window_s:
        raise CliError(
            f"the longest test part of the recordings is {longest:.2f} s, shorter than the "
            f"model's {window_s:g}-s window: record longer or raise --test-fraction "
            f"(now {fraction:g})"
        )
    return head


def identify(head: Sequence[Any], vehicle: Path, ukf_file: Path, log: Callable) -> Any:
    """Identify the axles on the recordings' parts before the test; write ``ukf_file``."""
    from sideslip_sim.axle_identification import identify_axles

    from .identify_axles import description_start, identified_file_text, recorded_runs

    start, source = description_start(vehicle)
    found = identify_axles(recorded_runs(head), start, None)
    recordings = len({r.bag for r in head})
    ukf_file.write_text(identified_file_text(found, recordings, source, ukf_file.stem))
    log(
        f"identified the UKF's axles before each recording's test part: cornering "
        f"stiffness front x{found.stiffness_ratio_front:.3f}, rear "
        f"x{found.stiffness_ratio_rear:.3f} of the description's ({found.points} points) "
        f"-> {ukf_file}"
    )
    return found


def interpolation(args: argparse.Namespace) -> float:
    """``--interpolate``'s share, or the default."""
    return DEFAULT_INTERPOLATION if args.interpolate is None else float(args.interpolate)


def rehearsal_runs(args: argparse.Namespace) -> int:
    """How many rehearsal runs the fit trains beside the recordings."""
    return DEFAULT_REHEARSAL_RUNS if args.rehearse is None else int(args.rehearse)


def simulate_rehearsal(
    args: argparse.Namespace, desc: Any, work: Path, log: Callable, started: float
) -> Path | None:
    """Simulate ``--rehearse`` runs of cars drawn around the description (the fleet
    sampler centred on it, as the description path does; held-out cars never) into
    ``work/rehearsal``; reused when a folder made with the same car, count and seed is
    there. None when no rehearsal is asked for."""
    from sideslip_sim.fleet import sample_fleet
    from sideslip_sim.generate import generate, prepare_output
    from sideslip_sim.held_out import held_out_digests
    from sideslip_sim.presets import FLEET_RUNS_PER_CAR, fleet_runs

    count = rehearsal_runs(args)
    if count == 0:
        return None
    out = work / "rehearsal"
    stamp = work / "rehearsal.json"
    from sideslip_sim import __version__ as sim_version

    # The simulator's version too: a folder from another simulator is not reused.
    key = {"car": desc.digest(), "runs": count, "seed": args.seed, "sim": sim_version}
    if (out / "index.json").exists() and stamp.exists():
        if json.loads(stamp.read_text()) == key:
            stage(log, started, f"rehearsal: {count} runs already simulated (reused)")
            return out
    seed = args.seed + REHEARSAL_SEED
    try:
        cars = sample_fleet(
            -(-count // FLEET_RUNS_PER_CAR),
            seed,
            prefix=f"{desc.name}_rehearsal",
            ranges=desc.ranges(),
            exclude_digests=held_out_digests(),
        ).vehicles
    except ValueError as err:  # FleetError: no plausible car around the description
        raise CliError(f"--rehearse: no cars like the description to simulate ({err})") from None
    stage(log, started, f"rehearsal: simulating {count} runs of {len(cars)} cars like the car")
    stamp.unlink(missing_ok=True)
    prepare_output(out, force=True)
    generate(fleet_runs(cars, count, seed), out, seed=seed, preset_name="fit-rehearsal",
             jobs=args.jobs, progress=not args.quiet)  # fmt: skip
    stamp.write_text(json.dumps(key) + "\n")
    return out


def scored_traces(
    args: argparse.Namespace,
    bags: Sequence[str],
    fraction: float | None,
    models: Sequence[Path],
    ukf_file: Path | None,
    described_ukf: Path | None,
    runs: Sequence[Any] | None = None,
) -> tuple[list[Any], list[str]]:
    """Every estimator's traces on each recording's test part (its last ``fraction``, as
    ``sideslip-train`` cut it; ``None``: the whole recording), resampled to the models'
    step, and the models' labels."""
    import numpy as np

    from sideslip_msgs_py.vehicle_description import VehicleDescription

    from .evaluate import Trace, evaluate_runs, model_label, physics_filter
    from .export import load_model
    from .splits import split_in_time

    loaded = [load_model(m) for m in models]
    meta = loaded[0][1]
    labels = [f"{model_label(m)} ({p.stem})" for (_, m), p in zip(loaded, models, strict=True)]
    if runs is None:
        runs, _ = _load(args, bags, step_s=meta.dt_s)
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


def check_test_bags(args: argparse.Namespace, meta: Any, log: Callable) -> list[Any]:
    """Read ``--test-bags`` as they will be scored (at the model's step), before anything
    is trained. Raises CliError (or DatasetError) when one is also a bag of ``--bags``
    (after resolving folders and links), when one is refused by the loader, or when one
    holds no stretch of a full window: every named test bag is scored, or none. Returns
    the runs, which the scoring after training uses (read once)."""
    from .dataset import find_bags

    if not args.test_bags:
        return []
    shared = sorted(set(find_bags(args.bags)) & set(find_bags(args.test_bags)))
    if shared:
        raise CliError(
            f"--test-bags and --bags both name {shared[0]}"
            + (f" (and {len(shared) - 1} more)" if len(shared) > 1 else "")
            + ": the separate recordings must be other drives than the fit's"
        )
    runs, report = _load(args, args.test_bags, step_s=meta.dt_s)
    if report.refused:
        raise CliError(f"--test-bags: {report.refused[0]}")
    scored = {r.bag for r in runs if len(r.samples) >= meta.window_steps}
    short = sorted({r.bag for r in runs} - scored)
    if short:
        raise CliError(
            f"--test-bags: {short[0]} holds no stretch of a full {meta.window_steps}-sample "
            "window at the model's step: record longer or leave it out"
        )
    log(f"--test-bags: {report}")
    return runs


def run(
    args: argparse.Namespace,
    desc: Any,
    shipped: str,
    fraction: float,
    log: Callable,
    started: float,
) -> int:
    """The recordings path of ``sideslip-fit`` (see module), with the test ``fraction``
    :func:`check_bag_arguments` gave; its exit code."""
    from sideslip_msgs_py.topic_map import TopicMapError
    from sideslip_sim.axle_identification import IdentificationError

    from .cli import train_main
    from .cli_errors import EXIT_BAD_INPUT
    from .dataset import DatasetError
    from .evaluate import FilterError
    from .export import load_model
    from .init_model import resolve

    work = args.work or args.out.with_suffix(".fit")
    work.mkdir(parents=True, exist_ok=True)
    measurable = args.features == "measurable"
    ukf_file = args.out.with_suffix(".ukf.yaml") if measurable else None
    described = work / "described.ukf.yaml" if measurable else None
    recipe = BAG_RECIPES[args.profile]
    report = work / "report"
    trained = False
    try:
        if args.out.stem == resolve(shipped).stem:
            # The card's rows are named by file: the two models would share one.
            raise CliError(f"--out {args.out}: name the fitted model other than {shipped}")
        _, meta = load_model(resolve(shipped))
        window_s = meta.window_steps * meta.dt_s
        test_runs = check_test_bags(args, meta, log)  # read once, at the models' step
        # Nothing of an earlier fit may stay beside this one's model.
        args.out.with_suffix(".md").unlink(missing_ok=True)
        shutil.rmtree(report, ignore_errors=True)
        head = split_recordings(args, fraction, window_s, measurable, log)
        found = None
        if measurable:
            assert ukf_file is not None and described is not None
            described.write_text(desc.ukf_params_yaml())
            stage(log, started, "identifying the UKF's axles")
            found = identify(head, args.vehicle, ukf_file, log)
        rehearsal = simulate_rehearsal(args, desc, work, log, started)
        train = ["--data", *args.bags, "--split", "time", "--test-fraction", f"{fraction!r}"]
        train += ["--rehearse", str(rehearsal)] if rehearsal is not None else []
        train += ["--init", shipped, "--out", str(args.out), "--force"]
        train += ["--run-dir", str(work / "train-run"), *recipe.train_args]
        train += ["--device", args.device, "--seed", str(args.seed)]
        train += ["--topic-map", str(args.topic_map)] if args.topic_map else []
        train += ["--max-epochs", str(args.max_epochs)] if args.max_epochs else []
        train += ["--learning-rate", repr(args.learning_rate)] if args.learning_rate else []
        train += ["--interpolate", repr(interpolation(args))]
        train += ["--quiet"] if args.quiet else []
        if measurable:
            train += ["--vehicle", str(args.vehicle), "--observer-params", str(ukf_file)]
            train += ["--car", "given"]
        with_rehearsal = f" + {rehearsal_runs(args)} rehearsal runs" if rehearsal else ""
        stage(log, started, f"fine-tuning {shipped}: {recipe.summary}{with_rehearsal}")
        code = train_main(train)
        if code != 0:
            return code
        trained = True
        models = [args.out, resolve(shipped)]
        report.mkdir(exist_ok=True)
        stage(log, started, "scoring on the test part of every recording")
        traces, labels = scored_traces(args, args.bags, fraction, models, ukf_file, described)
        test_part = _scored(traces, labels, report / "table.md", f"{desc.name}: test part")
        new_drives = None
        if args.test_bags:
            stage(log, started, "scoring on --test-bags")
            traces, _ = scored_traces(
                args, args.test_bags, None, models, ukf_file, described, test_runs
            )
            new_drives = _scored(
                traces, labels, report / "test-bags.md", f"{desc.name}: --test-bags"
            )
            share = narrow_interval(new_drives)
            if share is not None:
                print(
                    f"sideslip-fit: warning: only {share:.1%} of --test-bags' samples lie "
                    "inside the fitted model's ±1.96 σ: it is too narrow for those drives "
                    "(the card says more)",
                    file=sys.stderr,
                )
    except (CliError, DatasetError, TopicMapError, IdentificationError, FilterError) as err:
        after = f" ({args.out} was written; its card was not)" if trained else ""
        print(f"sideslip-fit: error: {err}{after}", file=sys.stderr)
        return EXIT_BAD_INPUT
    summary = {
        "bags": [str(b) for b in args.bags],
        "test_fraction": fraction,
        "models": {"fitted": labels[0], "shipped": labels[1]},
        "pooled": _pooled_json(test_part),
    }
    if new_drives is not None:
        summary["test_bags"] = [str(b) for b in args.test_bags]
        summary["test_bags_pooled"] = _pooled_json(new_drives)
    (report / "metrics.json").write_text(json.dumps(summary, indent=2, allow_nan=False) + "\n")
    train_metrics = json.loads((work / "train-run" / "metrics.json").read_text())
    from sideslip_msgs_py.artifact import read_artifact

    uncertainty = read_artifact(args.out)[1].uncertainty
    gentle = gentle_recordings(uncertainty)
    if gentle is not None:
        print(
            f"sideslip-fit: warning: the recordings stay under {math.ceil(gentle * 10) / 10:.1f} "
            "m/s² of lateral "
            "acceleration; beyond, the fitted model may err more than the shipped one, and "
            "on held-out cars such fits were no better than it on average (the card says "
            "more)",
            file=sys.stderr,
        )
    summary_text = recipe.summary + (
        f", beside {rehearsal_runs(args)} simulated runs of cars like it (`--rehearse`: "
        "training only)"
        if rehearsal_runs(args)
        else ""
    )
    if interpolation(args) < 1.0 and not train_metrics.get("kept_start_weights"):
        summary_text += (
            f"; the weights kept {interpolation(args):g} of the way from the start model's "
            "to the fine-tuned ones (`--interpolate`)"
        )
    card = model_card(args, summary_text, fraction, found, test_part, new_drives,
                      train_metrics, time.perf_counter() - started, uncertainty)  # fmt: skip
    args.out.with_suffix(".md").write_text(card)
    stage(log, started, f"wrote {args.out} and {args.out.with_suffix('.md')}")
    return 0


def _scored(traces: Sequence[Any], labels: Sequence[str], table: Path, title: str) -> Scored:
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


def _pooled_json(scored: Scored) -> list[dict[str, Any]]:
    from .evaluate import metrics_json

    return [
        {
            "estimator": n,
            **metrics_json(m),
            **({"coverage_95": scored.inside[n]} if n in scored.inside else {}),
        }
        for n, m in scored.rows.items()
    ]


def stage(log: Callable, started: float, what: str) -> None:
    """Log ``what`` with the seconds since ``started``."""
    log(f"[{time.perf_counter() - started:6.0f} s] {what}")
