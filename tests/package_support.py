"""Facts about the repository's ament_python packages, read from their files (not run)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def console_scripts(package: str) -> dict[str, str]:
    """``{script name: "module:function"}`` from the package's setup.py, read without running it."""
    tree = ast.parse((ROOT / package / "setup.py").read_text())
    for call in ast.walk(tree):
        if isinstance(call, ast.Call) and getattr(call.func, "id", None) == "setup":
            for keyword in call.keywords:
                if keyword.arg == "entry_points":
                    entries = ast.literal_eval(keyword.value).get("console_scripts", [])
                    return dict((part.strip() for part in entry.split("=", 1)) for entry in entries)
    return {}
