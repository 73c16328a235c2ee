"""The outputs of ``sideslip-train``: the model file and its run folder are never
overwritten without --force, and a --resume continues only the run its folder holds
(config.json records what the run was started with)."""

from __future__ import annotations

import json
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final

from .cli_errors import CliError

RESUME_KEYS: Final = (
    "data_digest",
    "features",
    "prior",
    "observer",
    "train_bags",
    "rehearsal_bags",
    "val_bags",
    "normalizer",
    "particle_threads",
    "train_config",
)
"""Entries of config.json a resumed PSO must share with the run it continues: the same
data, split, statistics, model and (results depend on it) threads per particle."""


def check_out(out: Path, *, run_dir: Path | None, force: bool, resume: bool) -> Path:
    """Refuse outputs that exist without ``force``; return the run folder (``run_dir``,
    default ``out`` with ``.run``; not made yet)."""
    if out.suffix != ".safetensors":
        raise CliError(f"--out {out}: must end in .safetensors")
    if out.exists() and not (force or resume):
        raise CliError(f"--out {out} exists; pass --force to replace it")
    run_dir = run_dir or out.with_suffix(".run")
    if resume:
        if not (run_dir / "pso_state.json").exists():
            raise CliError(f"--resume: no PSO state in {run_dir} (pso_state.json)")
    elif run_dir.exists() and not force:
        raise CliError(f"run folder {run_dir} exists; pass --force or --resume")
    elif run_dir.exists() and any(run_dir.iterdir()) and not (run_dir / "config.json").exists():
        # --force replaces a run folder, never an unrelated one (--run-dir . ...).
        raise CliError(f"run folder {run_dir} is not a sideslip-train run folder; not replacing it")
    return run_dir


def _make_run_dir(run_dir: Path, resume: bool) -> None:
    """Made only once the data has been accepted: a refused run leaves nothing behind."""
    if run_dir.exists() and not resume:
        shutil.rmtree(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)


def start_run_folder(run_dir: Path, config: Mapping[str, Any], *, resume: bool) -> None:
    """Make the run folder and write its config.json; on ``resume`` write nothing and
    refuse a ``config`` whose :data:`RESUME_KEYS` differ from the saved one's."""
    config_path = run_dir / "config.json"
    if resume:
        old = json.loads(config_path.read_text())
        # Compared as JSON would hold them (tuples as lists, paths as strings).
        json_config = json.loads(json.dumps({k: config[k] for k in RESUME_KEYS}, default=str))
        # A run folder from before a key existed holds its default.
        defaults = {"rehearsal_bags": []}
        changed = [k for k in RESUME_KEYS if old.get(k, defaults.get(k)) != json_config[k]]
        if changed:
            raise CliError(
                f"--resume: {run_dir} was started with other {', '.join(changed)}; "
                "resume with the original command"
            )
        return
    _make_run_dir(run_dir, resume=False)
    config_path.write_text(json.dumps(config, indent=2, default=str) + "\n")
