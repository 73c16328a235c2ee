"""The XML launch files name real executables, real parameter files and declared args.

``ros2 launch`` itself cannot run here: ROS 2's ``launch`` and ``launch_ros`` are not
published on PyPI (the ``launch`` project there is an unrelated 2017 package), and this
project gets ROS 2 from PyPI wheels. So these tests resolve statically what
``ros2 launch`` would resolve on a stock Jazzy install: every ``<node pkg= exec=>`` is a
console script that colcon installs to ``lib/<pkg>/``, every
``$(find-pkg-share pkg)/config/...`` is a YAML file the package installs, every
``$(var x)`` is declared by an ``<arg>``, every parameter a launch file sets is one the
node declares (in its parameter table), with the declared type (launch
types a value by parsing it as YAML; the nodes take an integer for a double and refuse
any other type change), and every launch argument that overrides a parameter defaults
to the YAML's value, or to the node's own default where the YAML does not set it: a
launch without arguments runs what the configuration files say.

Then what each launch file promises, resolved as ``ros2 launch`` would for given
arguments (:func:`launched_nodes`) and parsed with the tools' own argument parsers:
the player waits for the estimator's subscriptions, the recorder gets ``force``, and a
node that exits stops the launch.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml
from package_support import console_scripts

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("sideslip_msgs_py", "sideslip_sim", "sideslip_bags", "sideslip_estimator")
LAUNCH_FILES = {
    "sim_estimator": ROOT / "sideslip_estimator/launch/sim_estimator.launch.xml",
    "play_estimator": ROOT / "sideslip_estimator/launch/play_estimator.launch.xml",
    "sim_record": ROOT / "sideslip_sim/launch/sim_record.launch.xml",
}
FIND_PKG_SHARE = re.compile(r"\$\(find-pkg-share\s+([\w-]+)\)/([^\s\"$]+)")
VAR = re.compile(r"\$\(var\s+([\w-]+)\)")
# Parameters every rclpy node declares itself (and qos_overrides.*): not in the tables.
BUILT_IN_PARAMETERS = {"use_sim_time"}


def declared_parameters(package: str) -> dict[str, object]:
    """``{name: default}`` of every parameter the package's node declares, read from its
    declaration table; the estimator's back-ends' under ``<backend>.`` (it declares only
    the selected back-end's)."""
    if package == "sideslip_sim":
        from sideslip_sim.node_parameters import PARAMETERS as SIM

        return {p.name: p.default for p in SIM}
    if package == "sideslip_estimator":
        from sideslip_estimator.backends import BACKENDS
        from sideslip_estimator.node_parameters import PARAMETERS as ESTIMATOR

        declared: dict[str, object] = {p.name: p.default for p in ESTIMATOR}
        for name, factory in BACKENDS.items():
            declared |= {f"{name}.{p.name}": p.default for p in factory.parameters}
        return declared
    return {}


def launch_files() -> list[Path]:
    """Every launch file in our packages (those named above and any added later)."""
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg / "launch").glob("*.launch.xml"))


def parse(path: Path) -> ET.Element:
    root = ET.parse(path).getroot()
    assert root.tag == "launch", f"{path}: root element is <{root.tag}>, expected <launch>"
    return root


def attribute_values(root: ET.Element) -> list[tuple[ET.Element, str, str]]:
    return [(el, name, value) for el in root.iter() for name, value in el.attrib.items()]


def resolve_share(value: str) -> Path:
    """The source file behind ``$(find-pkg-share pkg)/rest`` (ament share == package folder)."""
    match = FIND_PKG_SHARE.fullmatch(value.strip())
    assert match, f"expected $(find-pkg-share PKG)/PATH, got {value!r}"
    return ROOT / match.group(1) / match.group(2)


def flatten(tree: dict, prefix: str = "") -> dict:
    """Nested YAML mappings as ROS names them: ``{limits: {stl_m: 0.5}}`` → ``limits.stl_m``."""
    flat: dict = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            flat.update(flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def node_parameters(path: Path, yaml_path: Path, node_name: str) -> dict:
    """The ``ros__parameters`` that a parameter file gives the node ``node_name``."""
    assert yaml_path.is_file(), f"{path.name}: parameter file {yaml_path} does not exist"
    doc = yaml.safe_load(yaml_path.read_text()) or {}
    assert isinstance(doc, dict), f"{yaml_path}: expected a mapping of node names"
    params: dict = {}
    for key, section in doc.items():
        if key in ("/**", node_name, f"/{node_name}"):
            assert "ros__parameters" in section, f"{yaml_path}: {key} has no ros__parameters"
            params.update(flatten(section["ros__parameters"]))
    assert params, (
        f"{path.name}: {yaml_path} has no section for node {node_name!r} "
        f"(top-level keys: {sorted(doc)}); the node would start with code defaults"
    )
    return params


def test_the_three_launch_files_exist() -> None:
    for name, path in LAUNCH_FILES.items():
        assert path.is_file(), f"launch file {name} missing at {path}"
    assert set(LAUNCH_FILES.values()) <= set(launch_files())


@pytest.mark.parametrize("path", launch_files(), ids=lambda p: p.name)
def test_every_node_is_an_installed_console_script(path: Path) -> None:
    nodes = parse(path).findall(".//node")
    assert nodes, f"{path}: no <node>"
    for node in nodes:
        pkg, exe = node.get("pkg"), node.get("exec")
        assert pkg in PACKAGES, f"{path}: <node pkg={pkg!r}> is not one of {PACKAGES}"
        scripts = console_scripts(pkg)
        assert exe in scripts, (
            f"{path}: <node exec={exe!r}> is not a console script of {pkg} "
            f"(setup.py declares {sorted(scripts)})"
        )


@pytest.mark.parametrize("path", launch_files(), ids=lambda p: p.name)
def test_every_find_pkg_share_file_exists_and_is_installed(path: Path) -> None:
    for _el, _name, value in attribute_values(parse(path)):
        for pkg, rest in FIND_PKG_SHARE.findall(value):
            assert pkg in PACKAGES, f"{path}: $(find-pkg-share {pkg}) is not one of ours"
            source = ROOT / pkg / rest
            assert source.is_file(), f"{path}: $(find-pkg-share {pkg})/{rest}: no {source}"
            # setup.py installs config/*.yaml and launch/*.launch.xml into share/<pkg>/.
            assert (rest.startswith("config/") and rest.endswith(".yaml")) or (
                rest.startswith("launch/") and rest.endswith(".launch.xml")
            ), f"{path}: {rest} is not in a folder that setup.py installs to share/{pkg}"


@pytest.mark.parametrize("path", launch_files(), ids=lambda p: p.name)
def test_every_var_is_declared_by_an_arg(path: Path) -> None:
    root = parse(path)
    declared = [arg.get("name") for arg in root.iter("arg")]
    assert len(declared) == len(set(declared)), f"{path}: an <arg> is declared twice"
    used = {var for _el, _n, value in attribute_values(root) for var in VAR.findall(value)}
    assert used <= set(declared), f"{path}: $(var) without <arg>: {sorted(used - set(declared))}"
    unused = set(declared) - used
    assert not unused, f"{path}: <arg> declared but never used: {sorted(unused)}"
    for arg in root.iter("arg"):
        assert arg.get("description"), f"{path}: <arg {arg.get('name')}> has no description"


@pytest.mark.parametrize("path", launch_files(), ids=lambda p: p.name)
def test_set_parameters_are_declared_typed_and_default_to_the_yaml(path: Path) -> None:
    root = parse(path)
    defaults = {arg.get("name"): arg.get("default") for arg in root.iter("arg")}
    for node in root.iter("node"):
        files = [p.get("from") for p in node.findall("param") if p.get("from")]
        overrides = [p for p in node.findall("param") if p.get("name")]
        if not overrides:
            continue
        name = node.get("name")
        assert name, f"{path}: node {node.get('exec')} sets parameters but has no name="
        assert files, f"{path}: node {name} sets parameters but loads no YAML file"
        yaml_params: dict = {}
        for file in files:
            yaml_params.update(node_parameters(path, resolve_share(file), name))
        declared = declared_parameters(node.get("pkg"))
        for key in yaml_params:
            if key in BUILT_IN_PARAMETERS or key.startswith("qos_overrides."):
                continue
            assert key in declared, f"{path}: the YAML for {name} sets undeclared {key!r}"
        for param in overrides:
            key, value = param.get("name"), param.get("value") or ""
            if key in BUILT_IN_PARAMETERS:
                continue
            assert key in declared, (
                f"{path}: node {name} sets {key!r}, which the node does not declare "
                f"(it declares {sorted(declared)})"
            )
            expected = yaml_params.get(key, declared[key])
            var = VAR.fullmatch(value)
            if var and defaults.get(var.group(1)) is None:
                continue  # a required argument: nothing to compare
            # launch infers a parameter's type by parsing the text as YAML.
            text = defaults[var.group(1)] if var else value
            launched = yaml.safe_load(text)
            int_for_double = type(launched) is int and type(expected) is float
            assert type(launched) is type(expected) or int_for_double, (
                f"{path}: {name}.{key} gets {text!r} ({type(launched).__name__}); the node "
                f"declares a {type(expected).__name__} and would refuse it"
            )
            if var:
                assert launched == expected, (
                    f"{path}: <arg {var.group(1)}> defaults to {launched!r} but {name}.{key} "
                    f"is {expected!r} without it (YAML, else the node's default)"
                )


def test_sim_time_follows_the_clock_source() -> None:
    """Whoever uses sim time has a /clock publisher in the same launch file."""
    sim = parse(LAUNCH_FILES["sim_estimator"])
    nodes = {n.get("exec"): n for n in sim.iter("node")}
    sim_params = {p.get("name"): p.get("value") for p in nodes["sim_node"].findall("param")}
    est_params = {p.get("name"): p.get("value") for p in nodes["estimator_node"].findall("param")}
    assert sim_params["publish_clock"] == est_params["use_sim_time"] == "$(var use_sim_time)"
    assert "use_sim_time" not in sim_params, "the simulator is the clock: it runs on wall time"

    play = parse(LAUNCH_FILES["play_estimator"])
    players = [n for n in play.iter("node") if n.get("exec") == "sideslip-play"]
    with_clock = [n for n in players if "--clock" in n.get("args", "").split()]
    assert [n.get("if") for n in with_clock] == ["$(var clock)"]
    assert all(n.get("unless") == "$(var clock)" for n in players if n not in with_clock)
    (estimator,) = [n for n in play.iter("node") if n.get("exec") == "estimator_node"]
    est_params = {p.get("name"): p.get("value") for p in estimator.findall("param")}
    assert est_params["use_sim_time"] == "$(var clock)"


# --- what the launch files promise, resolved for given arguments --------------------------------

TRUE_WORDS = {"true", "1"}  # launch's IfCondition: true/false/1/0, any case


def arguments(path: Path) -> dict[str, str | None]:
    """``{name: default}`` of every ``<arg>`` (None: required)."""
    return {arg.get("name"): arg.get("default") for arg in parse(path).iter("arg")}


def substitute(text: str, values: dict[str, str]) -> str:
    return VAR.sub(lambda m: values[m.group(1)], text)


def launched_nodes(path: Path, **given: str) -> list[tuple[ET.Element, list[str]]]:
    """The ``<node>`` elements that run for launch arguments ``given`` (else the
    defaults), each with its ``args`` resolved and split as ``ros2 launch`` splits them."""
    values = {k: v for k, v in arguments(path).items() if v is not None} | given
    nodes = []
    for node in parse(path).iter("node"):
        if_ = node.get("if")
        unless = node.get("unless")
        if if_ is not None and substitute(if_, values).lower() not in TRUE_WORDS:
            continue
        if unless is not None and substitute(unless, values).lower() in TRUE_WORDS:
            continue
        nodes.append((node, substitute(node.get("args", ""), values).split()))
    return nodes


def the_one(path: Path, exe: str, **given: str) -> tuple[ET.Element, list[str]]:
    found = [(n, a) for n, a in launched_nodes(path, **given) if n.get("exec") == exe]
    assert len(found) == 1, f"{path.name} with {given}: {len(found)} {exe} nodes run, expected 1"
    return found[0]


def test_launch_arguments_and_their_defaults() -> None:
    assert arguments(LAUNCH_FILES["sim_record"]) == {
        "scenario": "scen1",
        "out": None,
        "force": "false",
    }
    play = arguments(LAUNCH_FILES["play_estimator"])
    assert play == {
        "bag": None,
        "rate": "1.0",
        "clock": "true",
        "backend": "pso_lstm",
        "wait_s": "30.0",
    }
    (rtf,) = [
        a
        for a in parse(LAUNCH_FILES["sim_estimator"]).iter("arg")
        if a.get("name") == "real_time_factor"
    ]
    assert rtf.get("default") == "1.0"
    # The nodes take an integer for a double: the description must not ask for "2.0, not 2".
    assert "not 2" not in rtf.get("description", "")


@pytest.mark.parametrize("force", ["false", "true", "True", "0", "1"])
def test_sim_record_passes_force_to_the_recorder(force: str, tmp_path: Path) -> None:
    from sideslip_bags import record

    _node, args = the_one(
        LAUNCH_FILES["sim_record"], "sideslip-record", out=str(tmp_path / "bag"), force=force
    )
    options = record.parse_options(record.build_parser().parse_args(args))
    assert options.out == tmp_path / "bag"
    assert options.force is (force.lower() in TRUE_WORDS)


def test_sim_record_does_not_hang_when_the_recorder_exits() -> None:
    """The recorder refusing ``out`` (exit 2) stops the launch, and the simulator's wait
    for the recorder has a limit of its own."""
    path = LAUNCH_FILES["sim_record"]
    for force in ("false", "true"):
        for node, _args in launched_nodes(path, out="bags/x", force=force):
            assert node.get("on_exit") == "shutdown", f"{path.name}: {node.get('exec')}"
    sim, _ = the_one(path, "sim_node", out="bags/x")
    params = {p.get("name"): p.get("value") for p in sim.findall("param") if p.get("name")}
    assert int(params["wait_for_subscribers"]) >= 1
    assert 0.0 < float(params["wait_for_subscribers_timeout_s"]) <= 60.0


@pytest.mark.parametrize("clock", ["true", "false"])
def test_play_estimator_player_waits_for_the_estimator_inputs(clock: str, tmp_path: Path) -> None:
    from sideslip_bags import play
    from sideslip_msgs_py import topics

    path = LAUNCH_FILES["play_estimator"]
    _node, args = the_one(path, "sideslip-play", bag=str(tmp_path / "bag"), clock=clock)
    options = play.parse_options(play.build_parser().parse_args(args))
    assert options.bag == tmp_path / "bag"
    assert (options.clock_hz is not None) is (clock == "true")
    assert options.wait_subscribers_s == float(arguments(path)["wait_s"]) > 0.0
    # Exactly the estimator's inputs: nothing in this launch subscribes to ground truth,
    # so waiting for every played topic would always run into the timeout.
    assert sorted(options.wait_topics) == sorted(topics.SENSOR_TOPICS)
    assert options.wait_count == 1
    # A matched subscription is not yet a spinning node: the estimator gets time to start.
    assert 0.0 < options.delay_s <= 2.0
    for node, _args in launched_nodes(path, bag="b", clock=clock):
        assert node.get("on_exit") == "shutdown", f"{path.name}: {node.get('exec')}"


def test_every_node_of_sim_estimator_stops_the_launch_when_it_exits() -> None:
    path = LAUNCH_FILES["sim_estimator"]
    for node, _args in launched_nodes(path):
        assert node.get("on_exit") == "shutdown", f"{path.name}: {node.get('exec')}"
