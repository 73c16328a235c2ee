"""Typed declaration of ParameterSpecs on a real rclpy node (``sideslip_msgs_py.nodes``).

Each test creates nodes with parameter overrides, as ``--ros-args -p name:=value`` or a
launch file gives them, in its own context and DDS domain. Every double parameter of
both nodes (the simulator, the estimator and each of its back-ends) is checked.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import Parameter

import sideslip_sim.node as sim_node
from sideslip_estimator.backends import BACKENDS
from sideslip_estimator.node_parameters import PARAMETERS as ESTIMATOR_PARAMETERS
from sideslip_msgs_py.nodes.ros_parameters import ParameterTypeError, declare
from sideslip_msgs_py.parameter_spec import ParameterSpec

# (node, prefix, specs): what each node declares, the estimator's back-ends under their name.
DECLARED: list[tuple[str, str, tuple[ParameterSpec, ...]]] = [
    ("sim", "", sim_node.PARAMETERS),
    ("estimator", "", ESTIMATOR_PARAMETERS),
    *(("estimator", f"{name}.", tuple(f.parameters)) for name, f in BACKENDS.items()),
]
DOUBLES = [
    pytest.param(prefix, spec, id=f"{node}:{prefix}{spec.name}")
    for node, prefix, specs in DECLARED
    for spec in specs
    if isinstance(spec.default, float)
]


@pytest.fixture
def make_node(ros_domain) -> Iterator:
    """``make_node(overrides)``: a node in a fresh context, destroyed at teardown."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain.domain_id)
    nodes = []

    def make(overrides: dict[str, object]):
        params = [Parameter(name, value=value) for name, value in overrides.items()]
        node = rclpy.create_node(f"params{len(nodes)}", context=context, parameter_overrides=params)
        nodes.append(node)
        return node

    yield make
    for node in nodes:
        node.destroy_node()
    rclpy.shutdown(context=context)


def test_the_nodes_declare_doubles_at_all() -> None:
    names = {p.values[1].name for p in DOUBLES}
    assert {"real_time_factor", "rate_hz", "max_gap_s", "velocity_sigma_mps"} <= names
    assert len(DOUBLES) >= 30


@pytest.mark.parametrize(("prefix", "spec"), DOUBLES)
def test_every_double_parameter_takes_an_integer_as_a_double(make_node, prefix, spec) -> None:
    name = f"{prefix}{spec.name}"
    given = int(spec.default) + 2
    node = make_node({name: given})
    values = declare(node, [spec], prefix=prefix)
    assert values[spec.name] == float(given) and type(values[spec.name]) is float
    # Stored as a read-only double, as if it had been written 2.0.
    param = node.get_parameter(name)
    assert param.type_ == Parameter.Type.DOUBLE and param.value == float(given)
    described = node.describe_parameter(name)
    assert described.type == ParameterType.PARAMETER_DOUBLE
    assert described.read_only and not described.dynamic_typing
    assert described.description == spec.description
    result = node.set_parameters([Parameter(name, value=1.5)])[0]
    assert not result.successful and "read-only" in result.reason


def test_doubles_and_defaults_are_unchanged(make_node) -> None:
    rtf = next(p for p in sim_node.PARAMETERS if p.name == "real_time_factor")
    rate = next(p for p in sim_node.PARAMETERS if p.name == "rate_hz")
    values = declare(make_node({"real_time_factor": 0.25}), [rtf, rate])
    assert values == {"real_time_factor": 0.25, "rate_hz": 400.0}


@pytest.mark.parametrize(
    ("given", "kind"), [("fast", "string"), (True, "bool"), ([1.0, 2.0], "double_array")]
)
def test_another_type_for_a_double_is_refused_naming_parameter_and_value(
    make_node, given, kind
) -> None:
    rtf = next(p for p in sim_node.PARAMETERS if p.name == "real_time_factor")
    with pytest.raises(ParameterTypeError) as caught:
        declare(make_node({"real_time_factor": given}), [rtf])
    text = str(caught.value)
    assert "parameter real_time_factor must be a double" in text
    assert repr(given) in text and f"({kind})" in text


@pytest.mark.parametrize(("name", "given"), [("seed", 1.5), ("seed", "one"), ("loop", 1)])
def test_other_parameters_still_refuse_a_type_change(make_node, name, given) -> None:
    spec = next(p for p in sim_node.PARAMETERS if p.name == name)
    with pytest.raises(ParameterTypeError, match=f"parameter {name} must be a "):
        declare(make_node({name: given}), [spec])


TAKES_BOOL = [
    pytest.param(prefix, spec, id=f"{node}:{prefix}{spec.name}")
    for node, prefix, specs in DECLARED
    for spec in specs
    if spec.takes_bool
]


def test_mirror_average_is_a_string_that_takes_a_bool() -> None:
    assert {p.values[1].name for p in TAKES_BOOL} == {"mirror_average"}


@pytest.mark.parametrize(("prefix", "spec"), TAKES_BOOL)
@pytest.mark.parametrize(
    ("given", "stored"), [(True, "true"), (False, "false"), ("auto", "auto"), ("false", "false")]
)
def test_a_string_that_takes_a_bool_stores_it_as_true_or_false(
    make_node, prefix, spec, given, stored
) -> None:
    """``-p pso_lstm.mirror_average:=true`` (once a bool parameter) still works; the
    parameter is a read-only string from then on."""
    name = f"{prefix}{spec.name}"
    node = make_node({name: given})
    assert declare(node, [spec], prefix=prefix)[spec.name] == stored
    param = node.get_parameter(name)
    assert param.type_ == Parameter.Type.STRING and param.value == stored
    described = node.describe_parameter(name)
    assert described.type == ParameterType.PARAMETER_STRING and described.read_only


@pytest.mark.parametrize(("prefix", "spec"), TAKES_BOOL)
def test_a_string_that_takes_a_bool_refuses_a_number(make_node, prefix, spec) -> None:
    name = f"{prefix}{spec.name}"
    node = make_node({name: 1})
    with pytest.raises(ParameterTypeError, match=f"{name} must be a string or a bool, got 1"):
        declare(node, [spec], prefix=prefix)
