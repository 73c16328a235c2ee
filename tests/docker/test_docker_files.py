"""docker/Dockerfile, docker/compose.yaml and .dockerignore agree with the repository.

No Docker engine runs on the development machines (the client only), so the image is
never built here: these tests read the files and check what a build and
``docker compose up`` would rely on. Official base images, two stages with no build
tools in the final one, pins taken from constraints.txt, a colcon build of ros_ws; and
compose services that run executables the packages really install, on one ROS domain,
with a bag folder mounted for the recorder.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import pytest
import yaml
from package_support import console_scripts

ROOT = Path(__file__).resolve().parents[2]
DOCKERFILE = ROOT / "docker" / "Dockerfile"
COMPOSE = ROOT / "docker" / "compose.yaml"
DOCKERIGNORE = ROOT / ".dockerignore"
PACKAGES = ("sideslip_msgs_py", "sideslip_sim", "sideslip_bags", "sideslip_estimator")
INSTALL = PurePosixPath("/opt/sideslip/install")
# What only a build needs; none of it belongs in the final image.
BUILD_TOOLS = ("build-essential", "gcc", "g++", "colcon", "python3-pip", "python3-dev", "git")
SERVICE_EXECUTABLES = {
    "sim": ("sideslip_sim", "sim_node"),
    "estimator": ("sideslip_estimator", "estimator_node"),
    "recorder": ("sideslip_bags", "sideslip-record"),
}


# --- Dockerfile ------------------------------------------------------------------------------


@dataclass
class Instruction:
    keyword: str
    args: str


@dataclass
class Stage:
    image: str
    name: str | None
    instructions: list[Instruction]

    def args_of(self, keyword: str) -> list[str]:
        return [i.args for i in self.instructions if i.keyword == keyword]


def dockerfile_stages(path: Path = DOCKERFILE) -> list[Stage]:
    """Instructions grouped by ``FROM``, with ``\\`` continuations joined and comments dropped."""
    logical: list[str] = []
    pending = ""
    for raw in path.read_text().splitlines():
        line = raw.strip()
        if line.startswith("#") or (not line and not pending):
            continue
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        logical.append(pending + line)
        pending = ""
    assert not pending, f"{path}: the last instruction ends with a continuation"
    stages: list[Stage] = []
    for line in logical:
        keyword, _, args = line.partition(" ")
        keyword = keyword.upper()
        if keyword == "FROM":
            parts = args.split()
            name = parts[2] if len(parts) == 3 and parts[1].upper() == "AS" else None
            stages.append(Stage(parts[0], name, []))
        else:
            assert stages, f"{path}: {keyword} before the first FROM"
            stages[-1].instructions.append(Instruction(keyword, " ".join(args.split())))
    return stages


def test_dockerfile_builds_on_official_jazzy_images_in_two_stages() -> None:
    stages = dockerfile_stages()
    assert len(stages) >= 2, "multi-stage: a builder and a runtime stage"
    for stage in stages:
        assert re.fullmatch(r"ros:jazzy(-ros-base|-ros-core)?(-noble)?", stage.image), (
            f"FROM {stage.image}: use the official ros:jazzy images (Ubuntu noble)"
        )
    builder, final = stages[0], stages[-1]
    assert builder.name == "builder"
    # ros-base carries colcon; ros-core is what ros-base is built on, without build tools.
    assert builder.image.startswith("ros:jazzy-ros-base")
    assert final.image.startswith("ros:jazzy-ros-core")


def test_builder_runs_colcon_build_of_ros_ws() -> None:
    builder = dockerfile_stages()[0]
    copied = {args.split()[0] for args in builder.args_of("COPY")}
    assert {"ros_ws", *PACKAGES} <= copied, f"builder copies {sorted(copied)}"
    builds = [run for run in builder.args_of("RUN") if "colcon" in run and " build" in run]
    assert len(builds) == 1, "exactly one colcon build"
    (build,) = builds
    assert "--base-paths ros_ws/src" in build
    assert f"--install-base {INSTALL}" in build
    assert "--symlink-install" not in build, "the final stage gets a copy, not links to sources"
    # Run from the venv's python, so the console scripts' shebang is the venv's.
    assert "python /usr/bin/colcon" in build and "/opt/sideslip/venv/bin" in " ".join(
        builder.args_of("ENV")
    )


def test_python_dependencies_are_pinned_by_constraints_and_numpy_comes_from_apt() -> None:
    builder = dockerfile_stages()[0]
    runs = builder.args_of("RUN")
    venvs = [r for r in runs if "-m venv" in r]
    assert venvs and all("--system-site-packages" in r for r in venvs), (
        "the venv must see /opt/ros's rclpy and apt's numpy"
    )
    assert any(args.split()[0] == "constraints.txt" for args in builder.args_of("COPY"))
    pins = dict(
        line.split("==", 1)
        for line in (ROOT / "constraints.txt").read_text().splitlines()
        if "==" in line and not line.startswith("#")
    )
    pip_installs = [r for r in runs if "pip install" in r]
    assert pip_installs
    for run in pip_installs:
        assert "--no-cache-dir" in run, f"pip leaves a cache: {run}"
        assert "-c /tmp/pins.txt" in run
        # numpy from PyPI (2.x) would break rclpy's message modules built on apt's 1.26.
        assert re.search(r"grep -viE '\^\(numpy\|pyyaml\)=='", run), run
        requested = run.split("-c /tmp/pins.txt", 1)[1].split("&&", 1)[0].split()
        assert requested, run
        for name in requested:
            assert name in pins, f"{name} is installed but not pinned in constraints.txt"
            assert name.lower() not in ("numpy", "pyyaml"), f"{name} must come from apt"
        assert {"numba", "rosbags", "mcap", "tqdm"} <= set(requested)
    apt = " ".join(r for r in runs if "apt-get install" in r)
    assert "python3-numpy" in apt and "python3-yaml" in apt


def test_the_ukf_back_end_has_filterpy_and_apts_scipy_in_the_image() -> None:
    builder, runtime = dockerfile_stages()[0], dockerfile_stages()[-1]
    runs = " ".join(builder.args_of("RUN"))
    # Pure Python, pinned, without dependencies: scipy must be apt's (apt's numpy).
    assert re.search(r"pip install --no-cache-dir --no-deps -c /tmp/pins\.txt filterpy", runs)
    for stage in (builder, runtime):
        apt = " ".join(r for r in stage.args_of("RUN") if "apt-get install" in r)
        assert "python3-scipy" in apt


def test_final_stage_has_no_build_tools_and_no_caches() -> None:
    final = dockerfile_stages()[-1]
    for run in final.args_of("RUN"):
        assert "pip install" not in run, f"final stage installs with pip: {run}"
        assert "colcon" not in run, f"final stage runs colcon: {run}"
        if "apt-get install" in run:
            words = set(run.split())
            assert not words & set(BUILD_TOOLS), f"final stage installs {words & set(BUILD_TOOLS)}"
            assert "--no-install-recommends" in words
            assert "rm -rf /var/lib/apt/lists/*" in run, "apt lists left in the layer"
    copies = final.args_of("COPY")
    assert copies and all(c.startswith("--from=builder") for c in copies), copies
    assert {c.split()[1] for c in copies} == {"/opt/sideslip/venv", str(INSTALL)}
    builder_runs = " ".join(dockerfile_stages()[0].args_of("RUN"))
    assert "pip uninstall -y pip" in builder_runs, "the copied venv keeps no pip"


def test_entrypoint_sources_the_workspace_and_path_has_the_executables() -> None:
    final = dockerfile_stages()[-1]
    runs = " ".join(final.args_of("RUN"))
    assert f"source {INSTALL}/setup.bash" in runs
    assert final.args_of("ENTRYPOINT") == ['["/sideslip_entrypoint.sh"]']
    path = next(e for e in final.args_of("ENV") if e.startswith("PATH="))
    path_dirs = path.split()[0].removeprefix("PATH=").split(":")
    for pkg in ("sideslip_sim", "sideslip_bags", "sideslip_estimator"):
        assert f"{INSTALL}/{pkg}/lib/{pkg}" in path_dirs, f"{pkg}'s executables not on PATH"


def dockerignore_patterns() -> list[str]:
    lines = DOCKERIGNORE.read_text().splitlines()
    return [line.strip() for line in lines if line.strip() and not line.startswith("#")]


def test_dockerignore_sends_only_what_the_dockerfile_copies() -> None:
    patterns = dockerignore_patterns()
    assert patterns[0] == "*", "allow-list: ignore everything, then re-include"
    included = {p[1:] for p in patterns if p.startswith("!")}
    copied = {
        args.split()[0]
        for stage in dockerfile_stages()
        for args in stage.args_of("COPY")
        if not args.startswith("--from")
    }
    assert copied == included, f"COPY {sorted(copied)} vs .dockerignore ! {sorted(included)}"
    for local_only in ("ros_ws/build", "ros_ws/install", "ros_ws/log", "**/*.egg-info"):
        assert local_only in patterns, f".dockerignore should exclude {local_only}"


# --- compose.yaml ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def compose() -> dict:
    return yaml.safe_load(COMPOSE.read_text())


def command_words(service: dict) -> list[str]:
    """The words of a service's command; for ``bash -c SCRIPT``, those of SCRIPT."""
    command = service["command"]
    words = shlex.split(command) if isinstance(command, str) else list(command)
    if words[:2] == ["bash", "-c"]:
        words = shlex.split(words[2])
    return words[1:] if words[0] == "exec" else words


def test_services_sim_estimator_recorder_build_one_image(compose: dict) -> None:
    services = compose["services"]
    assert set(SERVICE_EXECUTABLES) <= set(services)
    images = {s["image"] for s in services.values()}
    assert len(images) == 1, f"one image for all services, got {images}"
    for name, service in services.items():
        build = service["build"]
        assert (COMPOSE.parent / build["context"]).resolve() == ROOT, name
        assert (ROOT / build["dockerfile"]).resolve() == DOCKERFILE, name


def test_services_share_one_ros_domain_and_the_host_network(compose: dict) -> None:
    services = compose["services"].values()
    domains = {s["environment"]["ROS_DOMAIN_ID"] for s in services}
    assert len(domains) == 1, f"services on different ROS domains: {domains}"
    assert {s.get("network_mode") for s in services} == {"host"}


def test_dds_data_goes_over_udp_so_any_host_user_receives_it(compose: dict) -> None:
    # Shared memory across containers, or towards a host user of another uid, gives
    # discovery without data: UDP by default (see the note in compose.yaml).
    for name, service in compose["services"].items():
        value = service["environment"]["FASTDDS_BUILTIN_TRANSPORTS"]
        assert re.fullmatch(r"\$\{FASTDDS_BUILTIN_TRANSPORTS:-UDPv4\}", value), name
        assert "ipc" not in service, f"{name}: no host IPC needed without shared memory"


def test_containers_run_as_a_non_root_user() -> None:
    runtime = DOCKERFILE.read_text().split("AS runtime", 1)[1]
    users = re.findall(r"^USER\s+(\S+)", runtime, flags=re.M)
    assert users and users[-1] not in {"root", "0"}, users
    assert re.search(r"useradd --uid \"\$\{SIDESLIP_UID\}\"", runtime)
    assert "ARG SIDESLIP_UID=1000" in runtime


def test_the_compose_simulator_loops_until_stopped(compose: dict) -> None:
    words = command_words(compose["services"]["sim"])
    i = words.index("loop:=true")
    assert words[i - 1] == "-p"
    # SIM_ARGS comes after it, so a user can still turn looping off.
    assert words.index("${SIM_ARGS:-}") > i


@pytest.mark.parametrize("name", sorted(SERVICE_EXECUTABLES))
def test_each_service_runs_a_real_installed_executable(compose: dict, name: str) -> None:
    pkg, executable = SERVICE_EXECUTABLES[name]
    words = command_words(compose["services"][name])
    assert words[0] == executable, f"service {name} runs {words[0]!r}, expected {executable!r}"
    assert executable in console_scripts(pkg), f"{executable} is not a console script of {pkg}"
    for i, word in enumerate(words[:-1]):
        if word == "--params-file":
            file = PurePosixPath(words[i + 1])
            rel = file.relative_to(INSTALL / pkg / "share" / pkg)
            assert rel.parts[0] == "config" and rel.suffix == ".yaml", file
            assert (ROOT / pkg / rel).is_file(), f"service {name}: {file} has no {pkg}/{rel}"


def test_recorder_writes_new_bags_into_a_mounted_folder(compose: dict) -> None:
    recorder = compose["services"]["recorder"]
    words = command_words(recorder)
    out = words[words.index("--out") + 1]
    mounts = {target: source for source, target in (v.rsplit(":", 1) for v in recorder["volumes"])}
    assert "/bags" in mounts, "the recorder needs the bag folder mounted"
    assert PurePosixPath(out).parent == PurePosixPath("/bags")
    assert "$(date" in out, "a fresh bag name per start: the recorder never overwrites"
    host = mounts["/bags"]
    default = re.fullmatch(r"\$\{\w+:-(.+)\}", host)
    host_dir = (COMPOSE.parent / (default.group(1) if default else host)).resolve()
    assert host_dir.is_relative_to(ROOT / "data"), f"bags go to git-ignored data/, not {host_dir}"
    # SIGINT lets the recorder write metadata.yaml before the container stops.
    assert recorder["stop_signal"] == "SIGINT"
