"""Parameter specs: parsing, validation reasons, descriptors, and the packaged spec of every node."""

from __future__ import annotations

import pytest
from rcl_interfaces.msg import ParameterType

from rh5_msgs_py.parameters import (
    ParameterSpecError,
    ParamSpec,
    declare_parameters,
    markdown_table,
    parameter_values,
    parse_spec,
)

DOCUMENT = {
    "parameters": {
        "rate_hz": {"type": "double", "default": 1000.0, "range": [1.0, 5000.0], "description": "Loop rate."},
        "transport": {
            "type": "string",
            "default": "udp",
            "choices": ["udp", "can"],
            "read_only": True,
            "description": "Link.",
        },
        "silent": {"type": "string_array", "default": [], "description": "Boards."},
    }
}


def test_parse_spec_reads_every_field() -> None:
    rate, transport, silent = parse_spec(DOCUMENT)
    assert rate == ParamSpec("rate_hz", "double", 1000.0, "Loop rate.", range=(1.0, 5000.0))
    assert transport.read_only
    assert transport.choices == ("udp", "can")
    assert silent.is_array


@pytest.mark.parametrize(
    ("value", "fragment"),
    [(0.0, "outside [1.0, 5000.0]"), ("fast", "expected double"), (True, "got a bool")],
)
def test_check_names_the_problem(value: object, fragment: str) -> None:
    rate = parse_spec(DOCUMENT)[0]
    assert fragment in rate.check(value)
    assert rate.check(500) == ""


def test_choices_and_arrays_are_checked_item_by_item() -> None:
    _, transport, silent = parse_spec(DOCUMENT)
    assert "not one of" in transport.check("serial")
    assert silent.check(["LLKnee_Act1"]) == ""
    assert "expected string_array" in silent.check([1])
    assert "expected a list" in silent.check("LLKnee_Act1")


@pytest.mark.parametrize(
    ("entry", "fragment"),
    [
        ({"type": "float", "default": 1.0, "description": "x"}, "unknown type"),
        ({"type": "double", "default": 1.0}, "description is required"),
        ({"type": "double", "default": 9.0, "range": [0, 1], "description": "x"}, "default 9.0 is invalid"),
        ({"type": "double", "default": 1.0, "description": "x", "min": 0}, "unknown keys"),
    ],
)
def test_malformed_specs_are_refused(entry: dict, fragment: str) -> None:
    with pytest.raises(ParameterSpecError, match=fragment):
        parse_spec({"parameters": {"p": entry}})


def test_descriptor_carries_type_range_and_read_only() -> None:
    rate, transport, _ = parse_spec(DOCUMENT)
    descriptor = rate.descriptor()
    assert descriptor.type == ParameterType.PARAMETER_DOUBLE
    assert descriptor.floating_point_range[0].to_value == 5000.0
    assert transport.descriptor().read_only
    assert "udp" in transport.descriptor().additional_constraints


def test_markdown_table_lists_every_parameter() -> None:
    table = markdown_table(parse_spec(DOCUMENT))
    assert table.count("\n") == 4
    assert "`rate_hz`" in table
    assert "read-only" in table


@pytest.mark.ros
def test_declared_parameters_take_whole_numbers_for_doubles_and_refuse_other_types(ros_graph: object) -> None:
    """A launch value of 1000 for a double (rclpy alone refuses an INTEGER there) is taken, a read-only one too;
    later sets are checked against the spec: a whole number passes, a string or an out-of-range value is refused."""
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    specs = parse_spec(
        {
            "parameters": {
                **DOCUMENT["parameters"],
                "fixed_hz": {"type": "double", "default": 250.0, "read_only": True, "description": "Fixed rate."},
            }
        }
    )
    node = Node(
        "parameter_probe",
        parameter_overrides=[Parameter("rate_hz", value=1000), Parameter("fixed_hz", value=500)],
    )
    try:
        declare_parameters(node, specs)
        values = parameter_values(node, specs)
        assert (values["rate_hz"], values["fixed_hz"]) == (1000.0, 500.0)
        assert isinstance(values["rate_hz"], float)  # what the node's code sees
        assert node.set_parameters([Parameter("rate_hz", value=2000)])[0].successful
        refused = node.set_parameters([Parameter("rate_hz", value="fast"), Parameter("rate_hz", value=9000.0)])
        assert [r.successful for r in refused] == [False, False]
        assert "expected double, got str" in refused[0].reason
        assert "9000" in refused[1].reason  # rclpy's range check of the descriptor answers first
        assert node.get_parameter("rate_hz").value == 2000
    finally:
        node.destroy_node()
