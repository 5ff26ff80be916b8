"""Parameter specs: parsing, validation reasons, descriptors, and the packaged spec of every node."""

from __future__ import annotations

import pytest
from rcl_interfaces.msg import ParameterType

from rh5_msgs_py.parameters import ParameterSpecError, ParamSpec, markdown_table, parse_spec

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
