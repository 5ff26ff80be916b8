"""The optional ankle strategy turns a tilted base back upright, and stays out of the way when off or stale."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from rh5_hyrodyn_mapper.model import build_model, q_index, standing_configuration
from rh5_joint_stabilizer.balance import ANKLE_JOINTS, AnkleBalanceCorrection, ankle_axes_world
from rh5_joint_stabilizer.reference import ReferenceSample
from rh5_msgs_py.names import FOOT_FRAMES, JOINT_INDEX, NUM_JOINTS


def base_in_sole(model: pin.Model, q: np.ndarray) -> np.ndarray:
    """Orientation of the base relative to the left sole."""
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    sole = data.oMf[model.getFrameId(FOOT_FRAMES["left"])]
    return sole.rotation.T @ data.oMi[1].rotation


@pytest.mark.parametrize("tilt", [np.array([0.0, 0.05, 0.0]), np.array([0.04, 0.0, 0.0]), np.array([0.03, -0.02, 0.0])])
def test_correction_turns_a_base_tilt_about_the_left_foot_back(tilt: np.ndarray) -> None:
    """The whole robot pivots with its left foot by ``tilt``; the corrected ankles bring the base back."""
    model = build_model(free_flyer=True)
    q = standing_configuration(model)
    correction = AnkleBalanceCorrection(1.0, 0.2, 10**9, ankle_axes_world())
    offsets = correction.offsets(tilt)
    q_corrected = q.copy()
    for name, offset in zip(ANKLE_JOINTS, offsets, strict=True):
        q_corrected[q_index(model)[JOINT_INDEX[name]]] += offset
    foot_tilted = pin.exp3(tilt)  # the left sole rotated by the tilt in the world
    before = pin.log3(foot_tilted @ base_in_sole(model, q))
    after = pin.log3(foot_tilted @ base_in_sole(model, q_corrected))
    assert np.linalg.norm(before - tilt) < 1e-4  # upright base over a level sole in the standing pose
    assert np.linalg.norm(after[:2]) < 0.05 * np.linalg.norm(tilt[:2])


def test_no_fresh_orientation_leaves_the_reference_alone() -> None:
    correction = AnkleBalanceCorrection(0.5, 0.1, timeout_ns=5_000_000, axes=ankle_axes_world())
    reference = ReferenceSample(np.zeros(NUM_JOINTS), np.zeros(NUM_JOINTS), np.zeros(NUM_JOINTS))
    assert correction(reference) is reference
    assert not correction.active
    correction.base_orientation.set(np.array([0.0, np.sin(0.025), 0.0, np.cos(0.025)]), stamp_ns=0)  # long ago
    assert correction(reference) is reference


def test_fresh_orientation_shifts_only_the_ankles_within_the_clip() -> None:
    correction = AnkleBalanceCorrection(0.5, 0.01, timeout_ns=10**9, axes=ankle_axes_world())
    correction.base_orientation.set(np.array([0.0, np.sin(0.05), 0.0, np.cos(0.05)]))
    reference = ReferenceSample(np.zeros(NUM_JOINTS), np.zeros(NUM_JOINTS), np.zeros(NUM_JOINTS))
    corrected = correction(reference)
    assert correction.active
    changed = np.flatnonzero(corrected.position)
    assert set(changed) <= {JOINT_INDEX[j] for j in ANKLE_JOINTS}
    assert np.abs(corrected.position).max() == pytest.approx(0.01)
