"""Loop-closure kinematics of every RH5 submechanism, as HyRoDyn models them (design/mechanisms.md).

``build_submechanisms()`` returns one immutable model per entry of ``rh5_msgs_py.names.SUBMECHANISMS``, in that
order and with its name, kind, joints and actuators:

* ``1-RRPR`` (Hip3, knees): :class:`Lambda1RRPR`, closed-form IK and FK;
* ``2-SPRR+1U`` (ankles): :class:`Ankle2SPRR1U`, closed-form IK, Newton FK;
* ``2-SPU+1U`` (torso pitch/roll, wrists): :class:`Platform2SPU1U`, closed-form IK, Newton FK;
* ``transmission`` (head) and ``serial`` (every other joint): :class:`LinearTransmission` / :class:`SerialJoint`.

Each model holds its constants as one row of the C kernels (``kernels.py``, ``unit_maps.c``), where the maths of
every kind lives once: a model's maps, RobotMapper's whole-robot maps and the 1 kHz single sample all run there.

The parallel units take their geometry from ``geometry.yaml`` (public RH5 submechanism files, cited there) and their
actuator limits from the paper's actuator table; the linear ones take the robot model's joint limits.
"""

from __future__ import annotations

import copy
import functools
from collections.abc import Mapping
from importlib import resources
from types import MappingProxyType
from typing import Any

import numpy as np
import yaml

import rh5_hyrodyn_mapper.model as robot_model
from rh5_msgs_py.names import JOINT_INDEX, SUBMECHANISMS, Submechanism

from .ankle_sprr import Ankle2SPRR1U
from .base import (
    ActuatorLimits,
    ForwardKinematicsError,
    KinematicsError,
    SingularityError,
    SubmechanismModel,
    actuator_limits,
)
from .lambda_rrpr import Lambda1RRPR
from .serial import HEAD_TRANSMISSION, LinearTransmission, SerialJoint, transmission_limits
from .spu import Platform2SPU1U, UniversalJointPlatform

__all__ = [
    "HEAD_TRANSMISSION",
    "ActuatorLimits",
    "Ankle2SPRR1U",
    "ForwardKinematicsError",
    "KinematicsError",
    "Lambda1RRPR",
    "LinearTransmission",
    "Platform2SPU1U",
    "SerialJoint",
    "SingularityError",
    "SubmechanismModel",
    "UniversalJointPlatform",
    "build_submechanisms",
    "load_geometry",
    "submechanism_geometry",
    "submechanism_models",
]

GEOMETRY_FILE = "geometry.yaml"


@functools.cache
def _raw_geometry() -> dict[str, Any]:
    text = resources.files(__package__).joinpath(GEOMETRY_FILE).read_text(encoding="utf-8")
    data = yaml.safe_load(text)
    if data.get("format_version") != 1:
        raise ValueError(f"{GEOMETRY_FILE}: unsupported format_version {data.get('format_version')!r}")
    return data


def load_geometry() -> dict[str, Any]:
    """A private copy of the parsed ``geometry.yaml`` (actuator_types, submechanisms as written)."""
    return copy.deepcopy(_raw_geometry())


def _mirror_entry(base: dict[str, Any], normal: list[float], swap_legs: bool) -> dict[str, Any]:
    n = np.asarray(normal, dtype=np.float64)
    n /= np.linalg.norm(n)
    mirror = np.eye(3) - 2.0 * np.outer(n, n)
    out = {k: v for k, v in base.items() if k not in ("legs", "joint_axes", "tree")}
    legs = [
        {key: (mirror @ np.asarray(value, dtype=np.float64)).tolist() for key, value in leg.items()}
        for leg in base["legs"]
    ]
    out["legs"] = legs[::-1] if swap_legs else legs
    return out


def submechanism_geometry(name: str) -> dict[str, Any]:
    """The resolved geometry entry of one parallel submechanism (``copy_of``/``mirror_of`` applied), a fresh copy."""
    entries = _raw_geometry()["submechanisms"]
    if name not in entries:
        raise KeyError(f"{GEOMETRY_FILE} has no submechanism {name!r}")
    entry = copy.deepcopy(entries[name])
    if "copy_of" in entry:
        base = submechanism_geometry(entry.pop("copy_of"))
        base.pop("tree", None)
        entry = {**base, **entry}
    elif "mirror_of" in entry:
        base = submechanism_geometry(entry.pop("mirror_of"))
        mirrored = _mirror_entry(base, entry.pop("mirror_normal"), bool(entry.pop("swap_legs", False)))
        entry = {**mirrored, **entry}
    return entry


def _limits(actuator_type: str, count: int) -> ActuatorLimits:
    spec = _raw_geometry()["actuator_types"][actuator_type]
    lo, hi = (float(v) for v in spec["stroke"])
    return actuator_limits(
        [lo] * count, [hi] * count, [float(spec["velocity_max"])] * count, [float(spec["force_max"])] * count
    )


def _parallel_model(spec: Submechanism) -> SubmechanismModel:
    g = submechanism_geometry(spec.name)
    if g["type"] != spec.kind:
        raise ValueError(f"{GEOMETRY_FILE}: {spec.name} is {g['type']!r}, rh5_msgs_py.names says {spec.kind!r}")
    limits = _limits(g["actuator_type"], len(spec.actuators))
    common = (spec.name, spec.joints, spec.actuators)
    if spec.kind == "1-RRPR":
        return Lambda1RRPR(
            *common,
            axis_point=g["axis_point"],
            axis=g["axis"],
            stator_pivot=g["stator_pivot"],
            rod_end=g["rod_end"],
            limits=limits,
        )
    legs = g["legs"]
    if spec.kind == "2-SPU+1U":
        return Platform2SPU1U(
            *common,
            joint_axes=g["joint_axes"],
            base_pivots=[leg["base_pivot"] for leg in legs],
            platform_pivots=[leg["platform_pivot"] for leg in legs],
            limits=limits,
        )
    if spec.kind == "2-SPRR+1U":
        return Ankle2SPRR1U.from_points(
            *common,
            joint_axes=g["joint_axes"],
            shank_pivots=[leg["shank_pivot"] for leg in legs],
            crank_pivots=[leg["crank_pivot"] for leg in legs],
            crank_axes=[leg["crank_axis"] for leg in legs],
            rod_ends=[leg["rod_end"] for leg in legs],
            limits=limits,
        )
    raise ValueError(f"{spec.name}: no model for kind {spec.kind!r}")


def _linear_model(spec: Submechanism, joint_limits: Any) -> SubmechanismModel:
    idx = [JOINT_INDEX[j] for j in spec.joints]
    lower, upper = joint_limits.position_lower[idx], joint_limits.position_upper[idx]
    velocity, torque = joint_limits.velocity_max[idx], joint_limits.torque_max[idx]
    if spec.kind == "serial":
        limits = actuator_limits(lower, upper, velocity, torque)
        return SerialJoint(spec.name, spec.joints, spec.actuators, limits=limits)
    if spec.kind == "transmission" and spec.name == "Head":
        limits = transmission_limits(HEAD_TRANSMISSION, lower, upper, velocity, torque)
        return LinearTransmission(
            spec.name, spec.kind, spec.joints, spec.actuators, matrix=HEAD_TRANSMISSION, limits=limits
        )
    raise ValueError(f"{spec.name}: no model for kind {spec.kind!r}")


@functools.cache
def build_submechanisms() -> tuple[SubmechanismModel, ...]:
    """Every submechanism model, in ``rh5_msgs_py.names.SUBMECHANISMS`` order (cached; the models are immutable)."""
    limits = robot_model.joint_limits()  # the robot model's joint limits (imports pinocchio on first use)
    models = []
    for spec in SUBMECHANISMS:
        if spec.kind in ("serial", "transmission"):
            models.append(_linear_model(spec, limits))
        else:
            models.append(_parallel_model(spec))
    return tuple(models)


@functools.cache
def submechanism_models() -> Mapping[str, SubmechanismModel]:
    """The models of ``build_submechanisms()`` by submechanism name (cached, read-only mapping)."""
    return MappingProxyType({m.name: m for m in build_submechanisms()})
