"""``sideslip-imu-scale``: Y_a's scale and bias from a car's own bags, without a reference.

A body-fixed IMU without an orientation reads gravity through the car's roll (9–13 %
more than the lateral acceleration), and a MEMS accelerometer's scale is good to about
1 %; the UKF-anchored models need Y_a right to about 1 %. This tool measures Y_a against
the speed and yaw rate of any driving with corners in it (no reference velocity or β:
:mod:`.accelerometer_scale`) and writes a topic map whose ``y_a_mps2`` takes the scale
and bias out, for ``sideslip-train``, ``sideslip-evaluate`` and the estimator node
(``topic_map_file``)::

    sideslip-imu-scale --data bags/ --write-topic-map my_car.topic_map.yaml
    sideslip-imu-scale --data bags/ --topic-map theirs.yaml --write-topic-map mine.yaml

Without ``--topic-map`` the bags are read on the contract's topics and the map written
names them. The estimate is of Y_a as the map reads it (scaled, levelled with an
attitude, moved to the CG), and the written map composes the fix with the map's own
``scale`` and ``offset``. That is exact unless the map also has ``imu.frame: body`` or
``imu.position_m``: those act after the channel's scale, so the fix scales their
corrections too (by κ: a second-order error); run the tool again on the written map to
check it reads 1. Exit 2 with one line for bad input or too little cornering.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from sideslip_estimator.accelerometer_scale import (
    MIN_CORNERING_S,
    AccelerometerScale,
    estimate_scale,
)
from sideslip_msgs_py.topic_map import TopicMap, TopicMapError, contract_topic_map

from .cli_errors import EXIT_BAD_INPUT, CliError
from .dataset import DatasetError, load_runs

CHANNELS = ("x_v_mps", "y_a_mps2", "yaw_rate_radps")
"""What the estimate reads."""
MAX_GAP_S = 0.5
"""Runs are split at longer gaps [s]; shorter ones (a 50-Hz IMU, jittery stamps) are the
estimate's to handle (:func:`~.accelerometer_scale.estimate_scale` cuts its stretches)."""


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="sideslip-imu-scale",
        description=__doc__.splitlines()[0],
        epilog="Needs at least 20 s of cornering above 1 m/s² at over 5 m/s; a few "
        "minutes of ordinary driving with turns in both directions is plenty.",
    )
    p.add_argument("--data", nargs="+", required=True, help="bags or folders of bags")
    p.add_argument("--topic-map", type=Path, help="read the bags through this map")
    p.add_argument("--write-topic-map", type=Path, help="write the map with the fix here")
    p.add_argument("--no-bias", action="store_true", help="fit the scale only (bias 0)")
    p.add_argument("--json", type=Path, help="write the estimate as JSON here")
    p.add_argument("--force", action="store_true", help="replace existing output files")
    return p


def fixed_topic_map(spec: dict[str, Any], found: AccelerometerScale) -> dict[str, Any]:
    """``spec`` (a topic map as a mapping) with ``y_a_mps2``'s scale and offset taking
    ``found``'s scale and bias out: (v·s0 + o0)·fix + offset."""
    out = copy.deepcopy(spec)
    try:
        channel = out["channels"]["y_a_mps2"]
    except (KeyError, TypeError):
        raise CliError("the topic map has no channels.y_a_mps2 to fix") from None
    fix, offset = found.channel_fix
    s0, o0 = float(channel.get("scale", 1.0)), float(channel.get("offset", 0.0))
    channel["scale"] = float(f"{s0 * fix:.6g}")
    channel["offset"] = float(f"{o0 * fix + offset:.6g}")
    return out


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        for out in (args.write_topic_map, args.json):
            if out is not None and out.exists() and not args.force:
                raise CliError(f"{out} exists; pass --force to replace it")
        if args.topic_map:
            topic_map: TopicMap | None = TopicMap.load(args.topic_map)  # checked, named
            spec = yaml.safe_load(args.topic_map.read_text(encoding="utf-8"))
            missing = [c for c in CHANNELS if c not in topic_map.channels]
            if missing:
                raise CliError(f"{args.topic_map}: maps no {', '.join(missing)} (needed)")
        else:
            spec, topic_map = contract_topic_map(), None
        runs, report = load_runs(
            args.data,
            require_truth=False,
            channels=CHANNELS,
            topic_map=topic_map,
            max_gap_s=MAX_GAP_S,
        )
        print(str(report), file=sys.stderr)  # (with the estimate's warning, if any)
        # The report's own estimate fits the bias; without it, once more.
        found = estimate_scale(runs) if args.no_bias else report.accelerometer_scale
        if found is None:
            raise CliError(
                f"too little cornering in {len(runs)} run(s) to measure Y_a's scale: needs "
                f"{MIN_CORNERING_S:g} s above 1 m/s² at over 5 m/s, with turns (a slalom "
                "at one frequency alone cannot tell the scale from the lateral velocity)"
            )
        fixed = fixed_topic_map(spec, found)
        fix, offset = found.channel_fix
        spread = "no spread: fewer than 3 chunks" if math.isnan(found.spread) else (
            f"scale ± {found.spread:.4f} over {found.chunks} chunk(s)")  # fmt: skip
        print(
            f"Y_a = {found.scale:.4f} × a_y {found.bias_mps2:+.3f} m/s² ({spread}; "
            f"{found.cornering_s:.0f} s of cornering)"
        )
        print(f"y_a_mps2: scale × {fix:.5f}, offset {offset:+.4f} m/s² on top of the map's own")
        if args.no_bias and found.warning:
            print(found.warning, file=sys.stderr)
        if args.write_topic_map:
            args.write_topic_map.parent.mkdir(parents=True, exist_ok=True)
            text = yaml.safe_dump(fixed, sort_keys=False)
            args.write_topic_map.write_text(text, encoding="utf-8")
            print(f"wrote {args.write_topic_map}")
        if args.json:
            body = {
                "scale": found.scale,
                "scale_spread": None if math.isnan(found.spread) else found.spread,
                "bias_mps2": found.bias_mps2,
                "chunks": found.chunks,
                "samples": found.samples,
                "cornering_s": found.cornering_s,
                "separation": found.separation,
                "y_a_mps2_fix": {"scale": fix, "offset": offset},
                "data": [str(d) for d in args.data],
            }
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(body, indent=2) + "\n", encoding="utf-8")
    except (CliError, DatasetError, TopicMapError, OSError, yaml.YAMLError) as err:
        print(f"sideslip-imu-scale: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return 0


if __name__ == "__main__":
    sys.exit(main())
