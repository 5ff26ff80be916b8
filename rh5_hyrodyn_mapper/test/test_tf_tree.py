"""The /tf tree: every link, transforms that compose to Pinocchio's forward kinematics, visuals for every body."""

from __future__ import annotations

import hashlib
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest

from rh5_hyrodyn_mapper.model import generate_urdf, model_hash, robot_model
from rh5_hyrodyn_mapper.tf_tree import KinematicTree, quaternion_multiply, urdf_links
from rh5_msgs_py.names import JOINT_NAMES


@pytest.fixture(scope="module")
def tree() -> KinematicTree:
    return KinematicTree(robot_model(free_flyer=False).urdf)


def _se3(translation: np.ndarray, quaternion: np.ndarray) -> pin.SE3:
    x, y, z, w = quaternion
    return pin.SE3(pin.Quaternion(w, x, y, z).toRotationMatrix(), np.asarray(translation))


def _world(link: str, edges: dict[str, tuple[str, pin.SE3]], root: str) -> pin.SE3:
    """A link's placement in the root frame, composed along the tree's edges."""
    placement = pin.SE3.Identity()
    while link != root:
        parent, local = edges[link]
        placement = local * placement
        link = parent
    return placement


def test_every_link_of_the_urdf_is_in_the_tree_once(tree: KinematicTree) -> None:
    links = urdf_links(robot_model(free_flyer=False).urdf)
    assert sorted(tree.links) == sorted(links)
    assert len(set(tree.links)) == len(tree.links)
    assert tree.root == "RH5_Root_Link"


def test_transforms_compose_to_pinocchio_forward_kinematics(tree: KinematicTree) -> None:
    model = robot_model(free_flyer=False).model
    data = model.createData()
    rng = np.random.default_rng(15)
    limits = robot_model().limits
    for _ in range(5):
        angles = rng.uniform(limits.position_lower, limits.position_upper)
        q = pin.neutral(model)
        q[robot_model(free_flyer=False).q_index] = angles
        pin.framesForwardKinematics(model, data, q)
        edges = {
            c: (p, _se3(t, r))
            for p, c, t, r in zip(
                tree.parents, tree.children, tree.origin_translation, tree.rotations(angles), strict=True
            )
        }
        edges |= {
            c: (p, _se3(t, r))
            for p, c, t, r in zip(
                tree.fixed_parents, tree.fixed_children, tree.fixed_translation, tree.fixed_rotation, strict=True
            )
        }
        for link in tree.links:
            expected = data.oMf[model.getFrameId(link, pin.FrameType.BODY)]
            got = _world(link, edges, tree.root)
            assert np.allclose(got.translation, expected.translation, atol=1e-9), link
            assert np.allclose(got.rotation, expected.rotation, atol=1e-9), link


def test_rotations_are_unit_quaternions_in_joint_order(tree: KinematicTree) -> None:
    angles = np.linspace(-1.0, 1.0, len(JOINT_NAMES))
    rotations = tree.rotations(angles)
    assert rotations.shape == (len(JOINT_NAMES), 4)
    assert np.allclose(np.linalg.norm(rotations, axis=1), 1.0)
    assert tree.joint_names == JOINT_NAMES
    # the product of a rotation and its conjugate is the identity
    conjugate = rotations * np.array([-1, -1, -1, 1])
    assert np.allclose(quaternion_multiply(rotations, conjugate), [0, 0, 0, 1])


def test_every_link_with_mass_has_a_visual_and_the_hash_ignores_them() -> None:
    text = generate_urdf(visuals=True)
    root = ET.fromstring(text)
    massive = [link for link in root.iter("link") if float(link.find("inertial/mass").get("value")) > 0.0]
    assert len(massive) >= 30
    missing = [link.get("name") for link in massive if link.find("visual") is None]
    assert missing == []
    shapes = {child.tag for v in root.iter("visual") for child in v.find("geometry")}
    assert shapes == {"box", "cylinder", "sphere"}
    assert generate_urdf() != text
    assert len(list(ET.fromstring(generate_urdf()).iter("visual"))) == 0
    # the hash tagging trajectory files stays that of the model without visuals
    assert model_hash() == hashlib.sha256(generate_urdf().encode()).hexdigest()
    assert model_hash() != hashlib.sha256(text.encode()).hexdigest()


def test_pinocchio_and_pybullet_read_the_urdf_with_visuals(tmp_path) -> None:
    import pybullet as pb

    text = generate_urdf(visuals=True)
    assert pin.buildModelFromXML(text).nq == len(JOINT_NAMES)
    path = tmp_path / "rh5.urdf"
    path.write_text(text)
    client = pb.connect(pb.DIRECT)
    try:
        robot = pb.loadURDF(str(path), physicsClientId=client)
        shapes = pb.getVisualShapeData(robot, physicsClientId=client)
        assert len(shapes) >= len(list(ET.fromstring(text).iter("visual")))
    finally:
        pb.disconnect(physicsClientId=client)
