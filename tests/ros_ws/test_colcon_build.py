"""``colcon build`` of ros_ws gives the install tree a stock ROS 2 user expects.

The workspace is built twice in a temporary folder (nothing is written into the
repository): a plain install and a ``--symlink-install``, with the colcon from this
venv and the ROS 2 Jazzy Python packages from PyPI wheels. Each build takes ~5 s.
What is checked is what ``ros2 run`` / ``ros2 launch`` rely on: the ament index marker,
``share/<pkg>/package.xml``, every console script under ``lib/<pkg>/``, the config and
launch files under ``share/<pkg>/``, and every Python sub-package on the path that
``install/setup.bash`` sets up; then an installed executable runs.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from package_support import console_scripts

ROOT = Path(__file__).resolve().parents[2]
WORKSPACE = ROOT / "ros_ws"
PACKAGES = ("sideslip_msgs_py", "sideslip_sim", "sideslip_bags", "sideslip_estimator")
COLCON = Path(sys.executable).parent / "colcon"
# Files the launch files and nodes look up under share/<pkg>/ at run time.
REQUIRED_SHARE_FILES = {
    "sideslip_sim": ["config/sim.yaml", "launch/sim_record.launch.xml"],
    "sideslip_estimator": [
        "config/estimator.yaml",
        "launch/sim_estimator.launch.xml",
        "launch/play_estimator.launch.xml",
    ],
}
# Console scripts the docs, launch files and compose file name; setup.py may add more.
REQUIRED_SCRIPTS = {
    "sideslip_sim": {"sideslip-generate", "sim_node", "sideslip-sim"},
    "sideslip_bags": {"sideslip-record", "sideslip-play"},
    "sideslip_estimator": {"estimator_node", "sideslip-estimator"},
}
BUILD_TIMEOUT_S = 120


def clean_env(tmp: Path) -> dict[str, str]:
    """This process's environment without any sourced ROS workspace or colcon defaults."""
    env = {
        k: v
        for k, v in os.environ.items()
        if not k.startswith(("AMENT_", "COLCON_", "ROS_"))
        and k not in ("PYTHONPATH", "CMAKE_PREFIX_PATH")
    }
    env["COLCON_HOME"] = str(tmp / "colcon_home")  # ignore the user's ~/.colcon/defaults.yaml
    return env


def in_workspace(install: Path, *command: str, env: dict[str, str]) -> subprocess.CompletedProcess:
    """Run ``command`` in bash after ``source install/setup.bash``, as a user would."""
    script = 'source "$1/setup.bash" && shift && exec "$@"'
    return subprocess.run(
        ["bash", "-c", script, "bash", str(install), *command],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )


def source_subpackages(package: str) -> list[str]:
    """Dotted names of every Python package (folder with __init__.py) in the source tree."""
    top = ROOT / package / package
    return sorted(
        ".".join(init.parent.relative_to(top.parent).parts)
        for init in top.rglob("__init__.py")
        if "__pycache__" not in init.parts
    )


def package_data_files(package: str) -> list[Path]:
    """Non-Python files inside the module folder, relative to it (what package_data ships)."""
    top = ROOT / package / package
    return sorted(
        f.relative_to(top)
        for f in top.rglob("*")
        if f.is_file() and f.suffix not in (".py", ".pyc") and "__pycache__" not in f.parts
    )


@pytest.fixture(scope="module", params=["plain", "symlink"])
def built(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory):
    """A colcon build of ros_ws in a temporary folder: (mode, install folder, env, base)."""
    mode = request.param
    base = tmp_path_factory.mktemp(f"colcon-{mode}")
    env = clean_env(base)
    command = [
        str(COLCON),
        "--log-base", str(base / "log"),
        "build",
        "--base-paths", str(WORKSPACE / "src"),
        "--build-base", str(base / "build"),
        "--install-base", str(base / "install"),
        "--event-handlers", "console_direct-", "console_stderr-", "desktop_notification-",
    ]  # fmt: skip
    if mode == "symlink":
        command.append("--symlink-install")
    result = subprocess.run(
        command, cwd=base, env=env, capture_output=True, text=True, timeout=BUILD_TIMEOUT_S
    )
    assert result.returncode == 0, (
        f"colcon build ({mode}) failed:\n{result.stdout}\n{result.stderr}"
    )
    return mode, base / "install", env, base


def test_src_links_the_four_packages_relatively() -> None:
    for pkg in PACKAGES:
        link = WORKSPACE / "src" / pkg
        assert link.is_symlink(), f"{link} should be a symlink to ../../{pkg}"
        target = os.readlink(link)
        assert not os.path.isabs(target), f"{link} -> {target}: use a relative link"
        assert link.resolve() == (ROOT / pkg).resolve()


def test_colcon_finds_four_ament_python_packages(tmp_path: Path) -> None:
    result = subprocess.run(
        [str(COLCON), "--log-base", os.devnull, "list", "--base-paths", str(WORKSPACE / "src")],
        env=clean_env(tmp_path),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
    found = {line.split()[0]: line.split()[-1] for line in result.stdout.splitlines() if line}
    assert found == dict.fromkeys(PACKAGES, "(ros.ament_python)"), result.stdout


def test_install_tree_has_index_manifest_and_every_console_script(built) -> None:
    mode, install, _env, _base = built
    for pkg in PACKAGES:
        prefix = install / pkg
        marker = prefix / "share/ament_index/resource_index/packages" / pkg
        assert marker.is_file(), f"{mode}: no ament index marker {marker}"
        manifest = prefix / "share" / pkg / "package.xml"
        assert manifest.is_file(), f"{mode}: no {manifest}"
        if mode == "symlink":
            assert manifest.is_symlink(), f"{mode}: {manifest} should link back to the source"
        scripts = console_scripts(pkg)
        assert REQUIRED_SCRIPTS.get(pkg, set()) <= set(scripts), f"{pkg}/setup.py: {scripts}"
        for script in scripts:
            exe = prefix / "lib" / pkg / script
            assert exe.is_file(), (
                f"{mode}: {script} not installed at {exe} (`ros2 run` looks there)"
            )
            assert os.access(exe, os.X_OK), f"{mode}: {exe} is not executable"


def test_install_tree_has_config_and_launch_files(built) -> None:
    mode, install, _env, _base = built
    for pkg in PACKAGES:
        share = install / pkg / "share" / pkg
        sources = sorted(
            p.relative_to(ROOT / pkg).as_posix()
            for pattern in ("config/*.yaml", "launch/*.launch.xml")
            for p in (ROOT / pkg).glob(pattern)
        )
        for rel in sorted({*sources, *REQUIRED_SHARE_FILES.get(pkg, [])}):
            assert (share / rel).is_file(), f"{mode}: {pkg} does not install {rel} to {share}"


def test_every_python_subpackage_and_data_file_is_on_the_workspace_path(built) -> None:
    """``source install/setup.bash`` puts every sub-package and shipped data file on the path."""
    mode, install, env, base = built
    # find_spec of a top-level name locates it without running its __init__.
    probe = (
        "import importlib.util, sys\n"
        "for top in sys.argv[1:]:\n"
        "    print(top, importlib.util.find_spec(top).submodule_search_locations[0])\n"
    )
    result = in_workspace(install, sys.executable, "-c", probe, *PACKAGES, env=env)
    assert result.returncode == 0, result.stderr
    locations = dict(line.split(" ", 1) for line in result.stdout.splitlines())
    for pkg in PACKAGES:
        where = Path(locations[pkg])
        # The workspace's copy (plain) or its build-folder links (symlink), never the repo's.
        assert where.is_relative_to(base), f"{mode}: {pkg} resolves to {where}, outside {base}"
        for sub in source_subpackages(pkg):
            rel = Path(*sub.split(".")[1:])
            assert (where / rel / "__init__.py").is_file(), f"{mode}: {sub} is not installed"
        # Data shipped inside the module (vehicles, tyres, model parameters): package_data.
        for data in package_data_files(pkg):
            assert (where / data).is_file(), f"{mode}: {pkg}/{data} is not installed"


def test_every_installed_executable_runs(built) -> None:
    """Each console script starts from the install tree and answers ``--help``.

    That imports its module (node, tool or CLI) and everything it needs, rclpy included.
    """
    mode, install, env, _base = built
    for pkg in PACKAGES:
        for script in console_scripts(pkg):
            exe = install / pkg / "lib" / pkg / script
            result = in_workspace(install, str(exe), "--help", env=env)
            assert result.returncode == 0, (
                f"{mode}: {exe} --help exited {result.returncode}:\n{result.stderr}"
            )
            assert result.stdout.strip(), f"{mode}: {exe} --help printed nothing"
    generate = in_workspace(
        install, str(install / "sideslip_sim/lib/sideslip_sim/sideslip-generate"), "--help", env=env
    )
    assert "usage: sideslip-generate" in generate.stdout
