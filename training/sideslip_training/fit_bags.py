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
import json
import math
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Final

from .cli_errors import CliError
from .fit_bags_args import BAG_RECIPES, folds, interpolation, learning_rate, rehearsal_runs
from .fit_bags_card import (
    gentle_recordings,
    model_card,
    narrow_interval,
    wide_interval,
)
from .fit_bags_scoring import (
    load_recordings,
    pooled_json,
    scored_table,
    scored_traces,
)

REHEARSAL_SEED: Final = 50_000
"""Added to ``--seed`` for the rehearsal's cars and runs: other cars than a description
fit's (``sideslip-fit`` without ``--bags``) with the same seed."""


def split_recordings(
    args: argparse.Namespace, fraction: float, window_s: float, measurable: bool, log: Callable
) -> list[Any]:
    """Each recording's part before its test part, at the recordings' own rate.

    Raises CliError, before anything is trained, when no recording's test part holds a
    full window of ``window_s``."""
    from .identify_axles import CHANNELS
    from .splits import split_in_time

    runs, report = load_recordings(
        args, args.bags, **({"channels": CHANNELS} if measurable else {})
    )
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

    # The simulator's version and the drives' sides too: a folder simulated by another
    # simulator, or before the drives turned both ways (2026-12-05), is not reused.
    key = {"car": desc.digest(), "runs": count, "seed": args.seed, "sim": sim_version,
           "sides": "both"}  # fmt: skip
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
    runs = fleet_runs(cars, count, seed, both_sides=True)
    generate(runs, out, seed=seed, preset_name="fit-rehearsal", jobs=args.jobs,
             progress=not args.quiet)  # fmt: skip
    stamp.write_text(json.dumps(key) + "\n")
    return out


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
    runs, report = load_recordings(args, args.test_bags, step_s=meta.dt_s)
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
    from .export import load_model
    from .filter_replay import FilterError
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
        rate = learning_rate(args, shipped)
        train += ["--learning-rate", repr(rate)] if rate is not None else []
        train += ["--interpolate", repr(interpolation(args, shipped))]
        train += ["--folds", str(folds(args))] if folds(args) > 1 else []
        train += ["--quiet"] if args.quiet else []
        if measurable:
            train += ["--vehicle", str(args.vehicle), "--observer-params", str(ukf_file)]
            train += ["--car", "given"]
        with_rehearsal = f" + {rehearsal_runs(args)} rehearsal runs" if rehearsal else ""
        chosen = f", epochs chosen over {folds(args)} folds" if folds(args) > 1 else ""
        stage(log, started, f"fine-tuning {shipped}: {recipe.summary}{with_rehearsal}{chosen}")
        code = train_main(train)
        if code != 0:
            return code
        trained = True
        models = [args.out, resolve(shipped)]
        report.mkdir(exist_ok=True)
        stage(log, started, "scoring on the test part of every recording")
        traces, labels = scored_traces(args, args.bags, fraction, models, ukf_file, described)
        test_part = scored_table(traces, labels, report / "table.md", f"{desc.name}: test part")
        new_drives = None
        if args.test_bags:
            stage(log, started, "scoring on --test-bags")
            traces, _ = scored_traces(
                args, args.test_bags, None, models, ukf_file, described, test_runs
            )
            new_drives = scored_table(
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
            share = wide_interval(new_drives)
            if share is not None:
                print(
                    f"sideslip-fit: note: {share:.1%} of --test-bags' samples lie inside the "
                    "fitted model's ±1.96 σ: wider than a 95 % interval needs on those drives "
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
        "pooled": pooled_json(test_part),
    }
    if new_drives is not None:
        summary["test_bags"] = [str(b) for b in args.test_bags]
        summary["test_bags_pooled"] = pooled_json(new_drives)
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
    alpha = interpolation(args, shipped)
    if alpha < 1.0 and not train_metrics.get("kept_start_weights"):
        summary_text += (
            f"; the weights kept {alpha:g} of the way from the start model's "
            "to the fine-tuned ones (`--interpolate`)"
        )
    card = model_card(args, summary_text, fraction, found, test_part, new_drives,
                      train_metrics, time.perf_counter() - started, uncertainty)  # fmt: skip
    args.out.with_suffix(".md").write_text(card)
    stage(log, started, f"wrote {args.out} and {args.out.with_suffix('.md')}")
    return 0


def stage(log: Callable, started: float, what: str) -> None:
    """Log ``what`` with the seconds since ``started``."""
    log(f"[{time.perf_counter() - started:6.0f} s] {what}")
