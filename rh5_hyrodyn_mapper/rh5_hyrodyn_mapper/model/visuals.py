"""Visual geometry of RH5 made from the model's own numbers: no meshes, nothing drawn by hand.

Each link with mass gets
- its *inertia-equivalent solid*: the uniform box with the link's mass and principal moments of inertia, placed
  at the centre of mass along the principal axes (a sphere of the same mean moment where the three moments are
  nearly equal, as for the head);
- a *bone* for each child joint more than ``BONE_MIN_LENGTH`` away: a cylinder from the link's origin to that
  joint, as thick as the link's mass spread over that length at ``BONE_DENSITY`` (thigh, shank, upper arm,
  forearm, neck, shoulders);
and every frame with a collision box (the soles) shows that box. Pure Python + numpy, deterministic.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

BONE_MIN_LENGTH = 0.05
"""m: joints closer to their parent link's origin get no bone."""
BONE_DENSITY = 1500.0
"""kg/m^3 of the bones' cylinders: the link's mass spread along the bone gives its radius."""
BONE_RADIUS = (0.02, 0.06)
"""m: the range a bone's radius is kept in."""
SPHERE_ISOTROPY = 1.6
"""A link whose largest principal moment is at most this times its smallest is drawn as a sphere."""
MIN_SIZE = 0.02
"""m: the smallest edge or radius drawn (a nearly massless link still shows)."""
COLOURS = {
    "body": "0.75 0.77 0.80 1",
    "bone": "0.25 0.27 0.30 1",
    "left": "0.80 0.35 0.25 1",
    "right": "0.25 0.45 0.80 1",
    "sole": "0.15 0.15 0.15 1",
}


@dataclass(frozen=True)
class Visual:
    """One URDF ``<visual>``: a shape in the link frame and its colour (URDF rgba text)."""

    shape: str  # box | cylinder | sphere
    size: tuple[float, ...]  # box: x y z edges; cylinder: radius, length; sphere: radius
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    rgba: str


def _rpy(rotation: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw (fixed axes x, y, z) of a rotation matrix (Pinocchio's ``rpy.matrixToRpy``)."""
    import pinocchio as pin  # noqa: PLC0415 (generating the URDF text needs no pinocchio otherwise)

    roll, pitch, yaw = pin.rpy.matrixToRpy(np.asarray(rotation, dtype=np.float64))
    return float(roll), float(pitch), float(yaw)


def _side(name: str) -> str:
    """Left/right limbs in their own colours (names as the public model: AL*, LL* left; AR*, LR* right)."""
    if name[:2] in ("AL", "LL"):
        return "left"
    if name[:2] in ("AR", "LR"):
        return "right"
    return "body"


def inertia_solid(name: str, inertial: Mapping[str, Any]) -> Visual | None:
    """The uniform box (or sphere) with the link's mass and principal moments, at its centre of mass."""
    mass = float(inertial["mass"])
    if mass <= 0.0:
        return None
    ixx, ixy, ixz, iyy, iyz, izz = (float(v) for v in inertial["inertia"])
    tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    moments, axes = np.linalg.eigh(tensor)
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    com = tuple(float(v) for v in inertial["com"])
    colour = COLOURS[_side(name)]
    if moments.max() <= SPHERE_ISOTROPY * max(moments.min(), 1e-12):
        radius = max(math.sqrt(2.5 * float(moments.mean()) / mass), MIN_SIZE)
        return Visual("sphere", (radius,), com, (0.0, 0.0, 0.0), colour)
    # A box of edges a, b, c has I_a = m (b^2 + c^2) / 12, ...: solve for the squared edges.
    total = moments.sum()
    edges = [math.sqrt(max(6.0 * (total - 2.0 * moment) / mass, 0.0)) for moment in moments]
    size = tuple(max(e, MIN_SIZE) for e in edges)
    return Visual("box", size, com, _rpy(axes), colour)


def bone(name: str, mass: float, to: Sequence[float]) -> Visual | None:
    """A cylinder from the link origin to a child joint at ``to`` (None when the joint is close)."""
    end = np.asarray(to, dtype=np.float64)
    length = float(np.linalg.norm(end))
    if length < BONE_MIN_LENGTH or mass <= 0.0:
        return None
    radius = min(max(math.sqrt(mass / (BONE_DENSITY * math.pi * length)), BONE_RADIUS[0]), BONE_RADIUS[1])
    z = end / length  # the cylinder's axis (URDF cylinders lie along z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    rotation = np.column_stack([x, np.cross(z, x), z])
    middle = tuple(float(v) for v in 0.5 * end)
    colour = COLOURS["bone"] if _side(name) == "body" else COLOURS[_side(name)]
    return Visual("cylinder", (radius, length), middle, _rpy(rotation), colour)


def link_visuals(params: Mapping[str, Any]) -> dict[str, list[Visual]]:
    """The visuals of every link of the parameter file, keyed by link name."""
    links: Mapping[str, Any] = params["links"]
    out: dict[str, list[Visual]] = {}
    children: dict[str, list[Sequence[float]]] = {}
    for joint in params["joints"].values():
        children.setdefault(joint["parent"], []).append(joint["xyz"])
    for name, frame in params["frames"].items():  # shoulders, head sensors: a frame carries a joint further on
        if name in children:
            children.setdefault(frame["parent"], []).append(frame["xyz"])
    for name, inertial in links.items():
        shapes = [inertia_solid(name, inertial)]
        shapes += [bone(name, float(inertial["mass"]), xyz) for xyz in children.get(name, [])]
        out[name] = [s for s in shapes if s is not None]
    for name, frame in params["frames"].items():
        box = frame.get("collision_box")
        if box is not None:
            xyz = tuple(float(v) for v in box["xyz"])
            out[name] = [Visual("box", tuple(float(v) for v in box["size"]), xyz, (0.0, 0.0, 0.0), COLOURS["sole"])]
    return out
