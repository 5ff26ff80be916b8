"""The pinocchio model of RH5 built from the generated URDF, with joint-space maps, limits and a standing pose.

Everything is derived once per process from ``rh5_parameters.yaml`` and cached; cached arrays are read-only
and :func:`build_model` hands out copies, so no caller can change what another one sees.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import FOOT_FRAMES, JOINT_NAMES, NUM_JOINTS

from .urdf import generate_urdf, load_parameters

__all__ = [
    "CONTACT_FRAMES",
    "NOMINAL_STANDING_JOINTS",
    "JointLimits",
    "RobotModel",
    "build_model",
    "joint_limits",
    "load_parameters",
    "model_hash",
    "q_index",
    "robot_model",
    "standing_configuration",
    "v_index",
]

IndexArray = npt.NDArray[np.intp]

CONTACT_FRAMES: Final[dict[str, tuple[str, ...]]] = {
    side: tuple(
        f"{sole.removesuffix('_Sole')}_Contact_{corner}"
        for corner in ("FrontLeft", "FrontRight", "RearLeft", "RearRight")
    )
    for side, sole in FOOT_FRAMES.items()
}
"""The four sole-corner contact frames of each foot (the 200 x 80 mm support rectangle), keyed like FOOT_FRAMES."""


def _frozen(array: npt.ArrayLike, dtype: Any = np.float64) -> Any:
    out = np.array(array, dtype=dtype)
    out.setflags(write=False)
    return out


@functools.cache
def _urdf() -> str:
    return generate_urdf()


@functools.cache
def model_hash() -> str:
    """SHA-256 (hex) of the generated URDF text: tags trajectory files with the exact model they were made for."""
    return hashlib.sha256(_urdf().encode("utf-8")).hexdigest()


@functools.cache
def _cached_model(free_flyer: bool) -> pin.Model:
    if free_flyer:
        return pin.buildModelFromXML(_urdf(), pin.JointModelFreeFlyer())
    return pin.buildModelFromXML(_urdf())


def build_model(free_flyer: bool = True) -> pin.Model:
    """A private copy of the pinocchio model (free-flyer root: nq = 39, nv = 38; fixed base: nq = nv = 32)."""
    return pin.Model(_cached_model(free_flyer))


def _joint_indices(model: pin.Model, attribute: str) -> IndexArray:
    ids = []
    for name in JOINT_NAMES:
        if not model.existJointName(name):
            raise KeyError(f"joint {name} is not in the pinocchio model")
        joint = model.joints[model.getJointId(name)]
        if joint.nq != 1 or joint.nv != 1:
            raise ValueError(f"joint {name} is not a 1-DoF joint in the pinocchio model")
        ids.append(getattr(joint, attribute))
    return _frozen(ids, np.intp)


@functools.cache
def _default_indices(free_flyer: bool, attribute: str) -> IndexArray:
    return _joint_indices(_cached_model(free_flyer), attribute)


def q_index(model: pin.Model | None = None) -> IndexArray:
    """Positions in pinocchio's q of the joints in JOINT_NAMES order (pinocchio orders joints depth-first).

    ``q[q_index()] = joint_vector`` writes a JOINT_NAMES-ordered vector into q; default model: free flyer.
    """
    return _default_indices(True, "idx_q") if model is None else _joint_indices(model, "idx_q")


def v_index(model: pin.Model | None = None) -> IndexArray:
    """Positions in pinocchio's v (and tau) of the joints in JOINT_NAMES order; default model: free flyer."""
    return _default_indices(True, "idx_v") if model is None else _joint_indices(model, "idx_v")


@dataclass(frozen=True, eq=False)
class JointLimits:
    """Joint limits in JOINT_NAMES order (rad, rad/s, Nm), from the paper's joint table (head: public model).

    ``velocity_range``/``torque_range`` are (32, 2) ``[lo, hi]``: parallel joints have a configuration-dependent
    limit between lo and hi (the mapper computes it); serial joints have lo == hi. ``*_max`` are the hi columns.
    """

    position_lower: FloatArray
    position_upper: FloatArray
    velocity_max: FloatArray
    torque_max: FloatArray
    velocity_range: FloatArray
    torque_range: FloatArray

    @property
    def configuration_dependent(self) -> npt.NDArray[np.bool_]:
        """True for the joints whose velocity or torque limit depends on the configuration (parallel joints)."""
        return (self.velocity_range[:, 0] < self.velocity_range[:, 1]) | (
            self.torque_range[:, 0] < self.torque_range[:, 1]
        )


def _range(value: float | Sequence[float]) -> tuple[float, float]:
    if isinstance(value, Sequence):
        lo, hi = (float(v) for v in value)
        return lo, hi
    return float(value), float(value)


@functools.cache
def joint_limits() -> JointLimits:
    """The limits of the parameter file (the same numbers the URDF ``<limit>`` tags carry, ranges kept)."""
    limits = load_parameters()["limits"]
    position = np.array([[float(v) for v in limits[n]["position"]] for n in JOINT_NAMES])
    velocity = np.array([_range(limits[n]["velocity"]) for n in JOINT_NAMES])
    torque = np.array([_range(limits[n]["torque"]) for n in JOINT_NAMES])
    return JointLimits(
        position_lower=_frozen(position[:, 0]),
        position_upper=_frozen(position[:, 1]),
        velocity_max=_frozen(velocity[:, 1]),
        torque_max=_frozen(torque[:, 1]),
        velocity_range=_frozen(velocity),
        torque_range=_frozen(torque),
    )


NOMINAL_STANDING_JOINTS: Final[FloatArray] = _frozen(np.zeros(NUM_JOINTS))
"""Nominal standing pose: all zero = upright, straight legs (knees at their 0 rad limit), arms hanging.

Chosen because the public model's zero pose already has both soles level and at the same height.
"""


def _has_free_flyer(model: pin.Model) -> bool:
    return model.njoints > 1 and model.joints[1].shortname() == "JointModelFreeFlyer"


def standing_configuration(model: pin.Model | None = None) -> FloatArray:
    """q of the nominal standing pose with the free flyer placed so that both soles lie flat on z = 0.

    The base keeps x = y = 0; its small rotation (~1e-5 rad, from the public model's rounded pi/2 = 1.5708)
    makes the soles exactly level. Without a free flyer this is the joint-space pose only.
    """
    model = _cached_model(True) if model is None else model
    q = pin.neutral(model)
    q[q_index(model)] = NOMINAL_STANDING_JOINTS
    if not _has_free_flyer(model):
        return q
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    soles = [data.oMf[model.getFrameId(FOOT_FRAMES[side], pin.FrameType.BODY)] for side in ("left", "right")]
    # Rotation that levels the soles (the mean of both feet's tilts; they are identical to ~1e-15 rad).
    level = pin.exp3(-0.5 * (pin.log3(soles[0].rotation) + pin.log3(soles[1].rotation)))
    height = np.mean([(level @ sole.translation)[2] for sole in soles])
    q[:3] = (0.0, 0.0, -height)
    q[3:7] = pin.Quaternion(level).coeffs()  # x, y, z, w as pinocchio stores it
    return q


@dataclass(frozen=True, eq=False)
class RobotModel:
    """Everything derived from the parameter file, bundled; ``model`` is shared, so treat it as read-only."""

    model: pin.Model
    urdf: str
    hash: str
    q_index: IndexArray
    v_index: IndexArray
    limits: JointLimits
    q_standing: FloatArray

    def create_data(self) -> pin.Data:
        """A fresh pinocchio Data (one per thread/computation)."""
        return self.model.createData()


@functools.cache
def robot_model(free_flyer: bool = True) -> RobotModel:
    """The cached :class:`RobotModel` (free-flyer root by default)."""
    model = _cached_model(free_flyer)
    return RobotModel(
        model=model,
        urdf=_urdf(),
        hash=model_hash(),
        q_index=_default_indices(free_flyer, "idx_q"),
        v_index=_default_indices(free_flyer, "idx_v"),
        limits=joint_limits(),
        q_standing=_frozen(standing_configuration(model)),
    )
