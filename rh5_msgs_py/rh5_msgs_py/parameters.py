"""Node parameters declared once, in one YAML file per node (type, default, description, validators).

The idea of generate_parameter_library (no wheel here): the YAML is the single source of
a node's parameters, from which the declarations, their descriptors, the validation of
every later ``set_parameters`` call and the README tables are made.

A spec file looks like::

    node: driver
    parameters:
      transport: {type: string, default: udp, choices: [udp, can], read_only: true,
                  description: Transport to the actuator boards.}
      rate_hz: {type: double, default: 1000.0, range: [1.0, 5000.0], description: Loop rate.}
"""

from __future__ import annotations

import array
import functools
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from importlib import resources
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType, SetParametersResult

if TYPE_CHECKING:
    from rclpy.node import Node
    from rclpy.parameter import Parameter

_TYPES: Mapping[str, tuple[int, type | tuple[type, ...]]] = {
    "bool": (ParameterType.PARAMETER_BOOL, bool),
    "int": (ParameterType.PARAMETER_INTEGER, int),
    "double": (ParameterType.PARAMETER_DOUBLE, (float, int)),
    "string": (ParameterType.PARAMETER_STRING, str),
    "bool_array": (ParameterType.PARAMETER_BOOL_ARRAY, bool),
    "int_array": (ParameterType.PARAMETER_INTEGER_ARRAY, int),
    "double_array": (ParameterType.PARAMETER_DOUBLE_ARRAY, (float, int)),
    "string_array": (ParameterType.PARAMETER_STRING_ARRAY, str),
}


class ParameterSpecError(ValueError):
    """A parameter spec file is malformed (a defect of the package, found at start-up)."""


@dataclass(frozen=True)
class ParamSpec:
    """One declared parameter: what it is, its default and what values it accepts."""

    name: str
    type: str
    default: Any
    description: str
    read_only: bool = False
    range: tuple[float, float] | None = None
    choices: tuple[Any, ...] | None = None

    def __post_init__(self) -> None:
        if self.type not in _TYPES:
            msg = f"parameter {self.name!r}: unknown type {self.type!r} (one of {sorted(_TYPES)})"
            raise ParameterSpecError(msg)
        if not self.description:
            msg = f"parameter {self.name!r}: a description is required"
            raise ParameterSpecError(msg)
        if problem := self.check(self.default):
            msg = f"parameter {self.name!r}: default {self.default!r} is invalid: {problem}"
            raise ParameterSpecError(msg)

    @property
    def is_array(self) -> bool:
        """Whether the parameter holds a list of values."""
        return self.type.endswith("_array")

    def check(self, value: Any) -> str:
        """Return why ``value`` is not acceptable, or '' when it is."""
        _, python_type = _TYPES[self.type]
        if self.is_array and not isinstance(value, list | tuple | array.array | np.ndarray):
            return f"expected a list of {self.type.removesuffix('_array')}"
        items = list(value) if self.is_array else [value]
        for item in items:
            if isinstance(item, bool) and python_type is not bool:
                return f"expected {self.type}, got a bool"
            if not isinstance(item, python_type):
                return f"expected {self.type}, got {type(item).__name__}"
            if self.range is not None and not (self.range[0] <= item <= self.range[1]):
                return f"{item!r} is outside [{self.range[0]}, {self.range[1]}]"
            if self.choices is not None and item not in self.choices:
                return f"{item!r} is not one of {list(self.choices)}"
        return ""

    def descriptor(self) -> ParameterDescriptor:
        """The ROS descriptor, so that operator tools show the description and limits."""
        kind, _ = _TYPES[self.type]
        descriptor = ParameterDescriptor(name=self.name, type=kind, description=self.description)
        descriptor.read_only = self.read_only
        if self.choices is not None:
            descriptor.additional_constraints = f"one of {list(self.choices)}"
        if self.range is not None and not self.is_array:
            lo, hi = self.range
            if self.type == "int":
                descriptor.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=0)]
            elif self.type == "double":
                descriptor.floating_point_range = [FloatingPointRange(from_value=float(lo), to_value=float(hi))]
        return descriptor


def parse_spec(document: Mapping[str, Any]) -> tuple[ParamSpec, ...]:
    """Build the specs from a parsed spec document (see the module docstring)."""
    try:
        entries = document["parameters"]
    except (KeyError, TypeError) as err:
        msg = "a parameter spec needs a top-level 'parameters' mapping"
        raise ParameterSpecError(msg) from err
    specs = []
    for name, entry in entries.items():
        unknown = set(entry) - {"type", "default", "description", "read_only", "range", "choices"}
        if unknown:
            msg = f"parameter {name!r}: unknown keys {sorted(unknown)}"
            raise ParameterSpecError(msg)
        specs.append(
            ParamSpec(
                name=name,
                type=entry["type"],
                default=entry["default"],
                description=" ".join(str(entry.get("description", "")).split()),
                read_only=bool(entry.get("read_only", False)),
                range=tuple(entry["range"]) if "range" in entry else None,
                choices=tuple(entry["choices"]) if "choices" in entry else None,
            )
        )
    return tuple(specs)


@functools.cache
def load_spec(package: str, resource: str) -> tuple[ParamSpec, ...]:
    """Load the parameter spec ``resource`` shipped inside python package ``package``."""
    text = resources.files(package).joinpath(resource).read_text(encoding="utf-8")
    return parse_spec(yaml.safe_load(text))


def declare_parameters(node: Node, specs: Iterable[ParamSpec]) -> None:
    """Declare every spec on ``node`` and refuse later sets that break a spec, with the reason."""
    by_name = {}
    for spec in specs:
        descriptor = spec.descriptor()
        if (spec.is_array and not spec.default) or spec.type in {"double", "double_array"}:
            # rclpy types an empty list as BYTE_ARRAY and would then refuse a string list, and it refuses a whole
            # number for a double (-p rate_hz:=1000, `rh5 experiment --param node.rate_hz=1000`): the spec's own
            # check (in the on-set callback below) enforces the type instead, whole numbers allowed for doubles.
            descriptor.dynamic_typing = True
        node.declare_parameter(spec.name, spec.default, descriptor)
        by_name[spec.name] = spec
        if problem := spec.check(node.get_parameter(spec.name).value):
            # A value given at launch (--ros-args -p / params file) overrides the default.
            msg = f"parameter {spec.name!r}: launch value is invalid: {problem}"
            raise ValueError(msg)

    refuse_unknown_overrides(node, by_name)

    def validate(params: list[Parameter]) -> SetParametersResult:
        for param in params:
            spec = by_name.get(param.name)
            if spec is not None and (problem := spec.check(param.value)):
                return SetParametersResult(successful=False, reason=f"{param.name}: {problem}")
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(validate)


def refuse_unknown_overrides(node: Node, specs: Mapping[str, ParamSpec]) -> None:
    """Refuse launch values (``-p``, ``--params-file``) for names the node does not have: a misspelt name would
    otherwise be dropped silently and its default used.

    :raises ValueError: naming the unknown names and the valid ones.
    """
    # rclpy keeps the launch values addressed to this node (by its name, or ``/**``) until they are declared.
    overrides = getattr(node, "_parameter_overrides", {})
    unknown = sorted(name for name in overrides if not node.has_parameter(name))
    if unknown:
        msg = (
            f"unknown parameter{'s' if len(unknown) > 1 else ''} {unknown} for node {node.get_name()!r}; "
            f"valid: {sorted(specs)} (and rclpy's use_sim_time)"
        )
        raise ValueError(msg)


def parameter_values(node: Node, specs: Iterable[ParamSpec]) -> dict[str, Any]:
    """Current values of the spec'd parameters, as plain Python values (doubles as floats, also when they were
    given as whole numbers)."""
    values = {}
    for spec in specs:
        value = node.get_parameter(spec.name).value
        if spec.type == "double":
            value = float(value)
        elif spec.type == "double_array":
            value = [float(item) for item in value]
        values[spec.name] = value
    return values


def markdown_table(specs: Iterable[ParamSpec]) -> str:
    """A Markdown table of the parameters, for the README (generated from the same spec)."""
    rows = ["| parameter | type | default | description |", "|---|---|---|---|"]
    for spec in specs:
        extra = []
        if spec.range is not None:
            extra.append(f"range {list(spec.range)}")
        if spec.choices is not None:
            extra.append(f"one of {list(spec.choices)}")
        if spec.read_only:
            extra.append("read-only")
        note = f" ({'; '.join(extra)})" if extra else ""
        rows.append(f"| `{spec.name}` | {spec.type} | `{spec.default!r}` | {spec.description}{note} |")
    return "\n".join(rows)
