"""What the studies of ``fit_bags_check.py`` folders share: their options and the car
files a fitted model is scored with (the description and the identified axle file, as
the node is given them)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from sideslip_msgs_py.vehicle_description import VehicleDescription


def study_parser(doc: str) -> argparse.ArgumentParser:
    """``--cars`` (fit_bags_check folders), ``--drives`` (the cars' other drives) and
    ``--out``."""
    p = argparse.ArgumentParser(description=doc.splitlines()[0])
    p.add_argument("--cars", type=Path, nargs="+", required=True, help="fit_bags_check folders")
    p.add_argument("--drives", type=Path, default=Path("data/fleet-val"))
    p.add_argument("--out", type=Path, required=True)
    return p


def fitted_car(work: Path, stem: str = "fitted") -> dict[str, Any]:
    """``predict_run``'s car arguments for the car fitted in ``work`` (its model and
    ``ukf`` file named ``stem``)."""
    return {
        "vehicle": VehicleDescription.load(work / "description.yaml"),
        "observer_params_file": str(work / f"{stem}.ukf.yaml"),
        "car": "given",
    }
