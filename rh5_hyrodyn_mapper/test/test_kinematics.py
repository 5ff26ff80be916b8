"""Acceptance tests of the submechanism kinematics (design/mechanisms.md section 9.1, items 1-10) for every parallel
instance (torso, both wrists, both Hip3, both knees, both ankles), the linear pass-through models, the assembly order
of build_submechanisms(), and the joint sign conventions against the project's serial tree model (pinocchio).

"Feasible" poses lie inside the tree model's joint ROM (model.joint_limits(), the paper's table) and need actuator
lengths inside the paper's strokes; each instance is sampled until 10,000 feasible poses are found.
"""

from __future__ import annotations

import functools
import math
import zlib

import numpy as np
import pinocchio as pin
import pytest

from rh5_hyrodyn_mapper.kinematics import (
    HEAD_TRANSMISSION,
    Ankle2SPRR1U,
    ForwardKinematicsError,
    KinematicsError,
    Lambda1RRPR,
    LinearTransmission,
    Platform2SPU1U,
    SerialJoint,
    SingularityError,
    SubmechanismModel,
    build_submechanisms,
    load_geometry,
    submechanism_geometry,
    submechanism_models,
)
from rh5_hyrodyn_mapper.model import build_model, joint_limits
from rh5_msgs_py.names import JOINT_INDEX, SUBMECHANISMS

PARALLEL = ("Body", "ALWrist", "ARWrist", "LLHip3", "LLKnee", "LLAnkle", "LRHip3", "LRKnee", "LRAnkle")
TWO_DOF = ("Body", "ALWrist", "ARWrist", "LLAnkle", "LRAnkle")
N_FEASIBLE = 10_000

# URDF actuator offsets at the zero pose (prismatic joint origins, |xyz|) [m]: hyrodyn/<unit>.urdf, joints *_Act1/2.
URDF_L0 = {
    "Hip3": (0.2974,),  # LRHip3.urdf LRHip3_Act1 xyz (0.2974, 0, 0)
    "Knee": (0.27341,),  # LRKnee.urdf LRKnee_Act1 xyz (0.27341, 0, 0)
    "Ankle": (0.26597, 0.26597),  # LLAnkle.urdf LLAnkle_Act1/2 xyz (0, 0, 0.26597)
    "Body": (0.24008, 0.24008),  # Body.urdf Body_Act1/2 xyz (0, 0, 0.24008)
    "Wrist": (0.26731, math.hypot(0.00070119, 0.26731)),  # ALWrist.urdf ALWrist_Act1 (0, 0, 0.26731), Act2 x 0.7 mm
}

# Feasible share of the ROM box reported in design/mechanisms.md 8.2 / 5.6 (an independent implementation).
BOX_FRACTION = {"2-SPRR+1U": 0.72, "Body": 0.57, "Wrist": 0.50}


def models() -> dict[str, SubmechanismModel]:
    return submechanism_models()


def rom(model: SubmechanismModel) -> tuple[np.ndarray, np.ndarray]:
    limits = joint_limits()
    idx = [JOINT_INDEX[j] for j in model.joints]
    return limits.position_lower[idx], limits.position_upper[idx]


def unit_key(name: str) -> str:
    for key in ("Hip3", "Knee", "Ankle", "Body", "Wrist"):
        if key in name:
            return key
    raise KeyError(name)


@functools.cache
def feasible(name: str) -> tuple[np.ndarray, np.ndarray, float]:
    """(y, l, feasible fraction of the ROM box): 10,000 random feasible poses, sampled in batches."""
    model = models()[name]
    lo, hi = rom(model)
    rng = np.random.default_rng(zlib.crc32(name.encode()))
    ys, ls, drawn = [], [], 0
    while sum(len(y) for y in ys) < N_FEASIBLE:
        y = rng.uniform(lo, hi, size=(20_000, model.dof))
        l = model.inverse(y)
        ok = np.all((l >= model.limits.length_min) & (l <= model.limits.length_max), axis=-1)
        ys.append(y[ok])
        ls.append(l[ok])
        drawn += len(y)
    count = sum(len(y) for y in ys)
    return np.concatenate(ys)[:N_FEASIBLE], np.concatenate(ls)[:N_FEASIBLE], count / drawn


# --- build_submechanisms: order, names, kinds, immutability -----------------------------------------------------------


def test_build_order_names_and_kinds() -> None:
    built = build_submechanisms()
    assert built is build_submechanisms()  # cached
    assert len(built) == len(SUBMECHANISMS)
    expected_class = {
        "1-RRPR": Lambda1RRPR,
        "2-SPRR+1U": Ankle2SPRR1U,
        "2-SPU+1U": Platform2SPU1U,
        "transmission": LinearTransmission,
        "serial": SerialJoint,
    }
    for model, spec in zip(built, SUBMECHANISMS, strict=True):
        assert (model.name, model.kind, model.joints, model.actuators) == tuple(spec)
        assert isinstance(model, expected_class[spec.kind])
        assert model.dof == len(spec.joints)
        for field in ("length_min", "length_max", "velocity_max", "force_max"):
            value = getattr(model.limits, field)
            assert value.shape == (model.dof,)
            assert not value.flags.writeable
        assert np.all(model.limits.length_min < model.limits.length_max)


def test_models_are_immutable() -> None:
    for model in build_submechanisms():
        with pytest.raises(AttributeError):
            model.name = "other"  # type: ignore[misc]
        with pytest.raises(AttributeError):
            model.limits = None  # type: ignore[assignment]
        assert not model.l0.flags.writeable
    ankle = models()["LLAnkle"]
    with pytest.raises(ValueError, match="read-only"):
        ankle.shank_pivots[0, 0] = 1.0


def test_parallel_limits_are_the_paper_actuator_table() -> None:
    # paper table "ROM of linear actuators" (rh5_paper_facts.yaml linear_actuators), SI units
    table = {"Hip3": (0.272, 0.431, 0.175, 4740), "Knee": (0.273, 0.391, 0.140, 5845)}
    table |= {"Ankle": (0.221, 0.331, 0.265, 2000), "Body": (0.195, 0.284, 0.291, 2716)}
    table |= {"Wrist": (0.235, 0.290, 0.038, 495)}
    for name in PARALLEL:
        limits = models()[name].limits
        lo, hi, v, f = table[unit_key(name)]
        np.testing.assert_array_equal(limits.length_min, lo)
        np.testing.assert_array_equal(limits.length_max, hi)
        np.testing.assert_array_equal(limits.velocity_max, v)
        np.testing.assert_array_equal(limits.force_max, f)


# --- 1. zero pose ----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", PARALLEL)
def test_zero_pose_lengths(name: str) -> None:
    model = models()[name]
    l0 = model.inverse(np.zeros(model.dof))
    np.testing.assert_array_equal(model.l0, l0)  # u(0) = IK(0) - l0 = 0
    # the URDF's pivot-to-pivot distance at the zero pose; the ankle's closest-point rod end is <= 1.2 nm shorter
    tol = 2e-9 if "Ankle" in name else 1e-9
    np.testing.assert_allclose(l0, URDF_L0[unit_key(name)], rtol=0, atol=tol)


# --- 2. + 9. round trip joints -> actuators -> joints, cold-started Newton -----------------------------------------


@pytest.mark.parametrize("name", PARALLEL)
def test_round_trip_joints_cold_start(name: str) -> None:
    model = models()[name]
    y, l, fraction = feasible(name)
    assert y.shape == (N_FEASIBLE, model.dof)
    y_back, iterations = model.forward_with_info(l)  # y_guess None: cold start J(0)^-1 (l - l0)
    assert np.max(np.abs(y_back - y)) <= 1e-9
    assert np.max(iterations) <= 8  # item 9: cold start <= 8 Newton iterations everywhere feasible (0: closed form)
    if model.dof == 2:
        key = model.kind if model.kind == "2-SPRR+1U" else unit_key(name)
        assert abs(fraction - BOX_FRACTION[key]) < 0.03
    else:
        assert fraction > 0.99  # the lambdas: only the ROM ends (Hip3 +17 deg, knee 88 deg) pass the stroke ends


@pytest.mark.parametrize("name", TWO_DOF)
def test_single_sample_and_any_leading_shape(name: str) -> None:
    model = models()[name]
    y, l, _ = feasible(name)
    y_single, iterations = model.forward_with_info(l[0])  # one sample: an int count, shape (m,)
    assert isinstance(iterations, int)
    np.testing.assert_allclose(y_single, y[0], rtol=0, atol=1e-11)
    shaped = y[:24].reshape(2, 3, 4, model.dof)
    assert model.inverse(shaped).shape == (2, 3, 4, 2)
    assert model.jacobian(shaped).shape == (2, 3, 4, 2, 2)
    assert model.bias(shaped, np.ones(2)).shape == (2, 3, 4, 2)
    np.testing.assert_allclose(model.forward(model.inverse(shaped)), shaped, atol=1e-11)


# --- 3. round trip actuators -> joints -> actuators -----------------------------------------------------------------


@pytest.mark.parametrize("name", PARALLEL)
def test_round_trip_actuators(name: str) -> None:
    model = models()[name]
    rng = np.random.default_rng(7)
    lo, hi = rom(model)
    margin = np.radians(10.0)
    # lengths of poses in a box 10 deg wider than the ROM: assemblable by construction, partly outside the stroke
    l = model.inverse(rng.uniform(lo - margin, hi + margin, size=(N_FEASIBLE, model.dof)))
    if model.kind != "2-SPRR+1U":  # every length pair of the stroke box is assemblable (not so for the ankle)
        l = np.concatenate([l, rng.uniform(model.limits.length_min, model.limits.length_max, size=l.shape)])
    assert np.max(np.abs(model.inverse(model.forward(l)) - l)) <= 1e-12


# --- 4. Jacobian vs central differences ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", PARALLEL)
def test_jacobian_vs_finite_differences(name: str) -> None:
    model = models()[name]
    y, _, _ = feasible(name)
    h = 1e-6
    jac = model.jacobian(y)
    fd = np.stack([(model.inverse(y + h * e) - model.inverse(y - h * e)) / (2 * h) for e in np.eye(model.dof)], axis=-1)
    relative = np.max(np.abs(jac - fd), axis=(-2, -1)) / np.max(np.abs(jac), axis=(-2, -1))
    assert np.max(relative) <= 1e-6


# --- 5. bias vs second differences -----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", PARALLEL)
def test_bias_vs_second_differences(name: str) -> None:
    model = models()[name]
    y, _, _ = feasible(name)
    rng = np.random.default_rng(11)
    yd = rng.uniform(-3.0, 3.0, size=y.shape)  # rad/s
    ydd = rng.uniform(-30.0, 30.0, size=y.shape)  # rad/s^2

    def second_difference(h: float) -> np.ndarray:
        path = [model.inverse(y + yd * t + 0.5 * ydd * t * t) for t in (-h, 0.0, h)]
        return (path[0] - 2.0 * path[1] + path[2]) / (h * h)

    fd = (4.0 * second_difference(1e-4) - second_difference(2e-4)) / 3.0  # Richardson: O(h^4) truncation
    predicted = np.einsum("...ij,...j->...i", model.jacobian(y), ydd) + model.bias(y, yd)
    assert np.max(np.abs(predicted - fd)) <= 1e-6  # m/s^2
    np.testing.assert_array_equal(model.bias(y, np.zeros_like(y)), 0.0)


# --- 6. + 7. statics: power conservation, force round trip, singularity guard -----------------------------------


@pytest.mark.parametrize("name", PARALLEL)
def test_power_conservation_and_force_round_trip(name: str) -> None:
    model = models()[name]
    y, _, _ = feasible(name)
    rng = np.random.default_rng(5)
    yd = rng.normal(size=y.shape)
    tau = rng.normal(scale=100.0, size=y.shape)
    f = model.forces(y, tau)
    l_dot = np.einsum("...ij,...j->...i", model.jacobian(y), yd)
    power_actuators = np.sum(f * l_dot, axis=-1)
    power_joints = np.sum(tau * yd, axis=-1)
    scale = np.linalg.norm(f, axis=-1) * np.linalg.norm(l_dot, axis=-1)
    assert np.max(np.abs(power_actuators - power_joints) / scale) <= 1e-9
    back = model.torques(y, f)
    assert np.max(np.abs(back - tau) / np.linalg.norm(tau, axis=-1, keepdims=True)) <= 1e-10
    jac = model.jacobian(y)  # callers may pass J they already have
    np.testing.assert_array_equal(model.forces(y, tau, jac=jac), f)
    np.testing.assert_array_equal(model.torques(y, f, jac=jac), back)
    for k in range(20):  # single-sample path
        np.testing.assert_allclose(model.forces(y[k], tau[k]), f[k], rtol=1e-12)
        np.testing.assert_allclose(model.forces(y[k], tau[k], 1e6, jac[k]), f[k], rtol=1e-12)
        np.testing.assert_allclose(model.torques(y[k], f[k]), back[k], rtol=1e-12)
        np.testing.assert_allclose(model.torques(y[k], f[k], jac=jac[k]), back[k], rtol=1e-12)
    condition = model.condition(y)
    assert np.max(condition) < 5.0  # far from singular inside the feasible ROM (ankle <= 4.2, 5.6)


def _singular_pose(model: SubmechanismModel) -> np.ndarray:
    """A pose with det J = 0 (to rounding): bisection along the first ray from y = 0 where det J changes sign."""
    det0 = np.linalg.det(model.jacobian(np.zeros(2)))
    for angle in np.linspace(0.0, 2 * np.pi, 16, endpoint=False):
        direction = np.array([np.cos(angle), np.sin(angle)])
        t = np.linspace(0.0, np.pi, 400)
        dets = np.linalg.det(model.jacobian(t[:, None] * direction))
        change = np.nonzero(np.sign(dets) != np.sign(det0))[0]
        if change.size:
            a, b = t[change[0] - 1], t[change[0]]
            for _ in range(80):
                mid = 0.5 * (a + b)
                same = np.sign(np.linalg.det(model.jacobian(mid * direction))) == np.sign(det0)
                a, b = (mid, b) if same else (a, mid)
            return a * direction
    raise AssertionError(f"{model.name}: no singular pose found")


@pytest.mark.parametrize("name", TWO_DOF)
def test_singularity_guard_two_dof(name: str) -> None:
    model = models()[name]
    y_singular = _singular_pose(model)
    assert model.condition(y_singular) > 1e6
    tau = np.array([10.0, -5.0])
    with pytest.raises(SingularityError, match=name):
        model.forces(y_singular, tau)
    with pytest.raises(SingularityError, match=name):  # batch: one singular sample refuses the whole call
        model.forces(np.stack([np.zeros(2), y_singular]), np.stack([tau, tau]))
    with pytest.raises(SingularityError):  # a tiny max_condition refuses even the zero pose
        model.forces(np.zeros(2), tau, max_condition=1.0 - 1e-12)
    model.forces(np.zeros(2), tau)  # but not with the default


@pytest.mark.parametrize("name", ["LLHip3", "LLKnee"])
def test_singularity_guard_lambda(name: str) -> None:
    model = models()[name]
    assert isinstance(model, Lambda1RRPR)
    y_singular = np.array([-model.phi0 + 1e-9])  # theta ~ 0: the actuator line passes through the joint axis
    assert abs(model.jacobian(y_singular)[0, 0]) < 1e-9
    with pytest.raises(SingularityError, match=name):
        model.forces(y_singular, np.array([100.0]))
    with pytest.raises(SingularityError, match=name):
        model.forces(np.array([[0.0], y_singular[0:1]]), np.array([[1.0], [1.0]]))
    # the largest moment arm is min(l1, l2) of the planar design (design 3.4): Hip3 114.0 mm, knee 85.0 mm
    assert model.moment_arm_max == pytest.approx(0.11402 if "Hip3" in name else 0.08500, abs=2e-5)


# --- FK errors for unreachable lengths ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["LLHip3", "LRKnee"])
def test_forward_error_lambda(name: str) -> None:
    model = models()[name]
    for bad in (0.9, 0.05, math.nan):
        with pytest.raises(ForwardKinematicsError, match=rf"{name}: .*residual"):
            model.forward(np.array([bad]))
    with pytest.raises(ForwardKinematicsError, match=r"1 of 3 sample"):
        model.forward(np.array([[0.3], [0.9], [0.31]]))


@pytest.mark.parametrize("name", TWO_DOF)
def test_forward_error_two_dof(name: str) -> None:
    model = models()[name]
    lo, hi = model.limits.length_min[0], model.limits.length_max[0]
    unreachable = [np.array([0.02, 0.9]), np.array([3.0, 3.0]), np.array([math.nan, lo])]
    if model.kind == "2-SPRR+1U":
        unreachable.append(np.array([lo + 0.008, hi - 0.004]))  # inside the stroke box, not assemblable
    grid = np.linspace(-np.pi, np.pi, 721)
    poses = np.stack(np.meshgrid(grid, grid, indexing="ij"), axis=-1).reshape(-1, 2)
    reachable = model.inverse(poses)
    for l in unreachable:
        if np.all(np.isfinite(l)):  # justify "unreachable": no pose on a 0.5 deg grid comes within 0.5 mm
            assert np.min(np.max(np.abs(reachable - l), axis=-1)) > 5e-4
        with pytest.raises(ForwardKinematicsError, match=rf"{name}: .*residual .* m after {model.max_iterations}"):
            model.forward(l)
        with pytest.raises(ForwardKinematicsError, match=r"1 of 2 sample"):
            model.forward(np.stack([model.l0, l]), y_guess=np.zeros(2))
    with pytest.raises(KinematicsError, match=name):
        model.forward(np.zeros(3))


# --- 8. branch: sign(det J) constant over the feasible ROM and along trajectories ----------------------------


@pytest.mark.parametrize("name", PARALLEL)
def test_working_mode_constant(name: str) -> None:
    model = models()[name]
    y, _, _ = feasible(name)
    det = np.linalg.det(model.jacobian(y))
    det0 = np.linalg.det(model.jacobian(np.zeros(model.dof)))
    assert np.all(np.sign(det) == np.sign(det0))
    assert np.min(np.abs(det)) > 0.0


# --- 9. warm start along a 1 kHz trajectory --------------------------------------------------------------------------


def _trajectory(model: SubmechanismModel, seconds: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smooth y(t) at 1 kHz (sums of sines) inside the feasible ROM (largest of a few amplitudes), y_dot, y_ddot."""
    lo, hi = rom(model)
    t = np.arange(0.0, seconds, 1e-3)[:, None]
    w1, w2 = 2 * np.pi * np.array([0.9, 1.3][: model.dof]), 2 * np.pi * np.array([2.1, 3.7][: model.dof])
    for share in (0.4, 0.3, 0.2, 0.1):
        centre, amplitude = 0.5 * (lo + hi), share * (hi - lo)
        y = centre + amplitude * (0.7 * np.sin(w1 * t) + 0.3 * np.sin(w2 * t + 0.4))
        l = model.inverse(y)
        if np.all((l >= model.limits.length_min) & (l <= model.limits.length_max)):
            yd = amplitude * (0.7 * w1 * np.cos(w1 * t) + 0.3 * w2 * np.cos(w2 * t + 0.4))
            ydd = -amplitude * (0.7 * w1**2 * np.sin(w1 * t) + 0.3 * w2**2 * np.sin(w2 * t + 0.4))
            return y, yd, ydd
    raise AssertionError(f"{model.name}: no feasible test trajectory")


@pytest.mark.parametrize("name", PARALLEL)
def test_trajectory_warm_start(name: str) -> None:
    model = models()[name]
    y, yd, ydd = _trajectory(model)
    l = model.inverse(y)
    y_prev = np.zeros(model.dof)
    worst, iterations = 0.0, []
    det_signs = set()
    for k in range(len(y)):  # the mapper's per-sample pattern: warm start from the previous sample
        y_k, count = model.forward_with_info(l[k], y_guess=y_prev)
        iterations.append(count)
        worst = max(worst, float(np.max(np.abs(y_k - y[k]))))
        det_signs.add(float(np.sign(np.linalg.det(model.jacobian(y_k)))))
        y_prev = y_k
    assert worst <= 1e-9
    assert max(iterations) <= 4
    assert len(det_signs) == 1
    # the batch warm start gives the same answer
    y_batch, its = model.forward_with_info(l, y_guess=np.vstack([np.zeros(model.dof), y[:-1]]))
    assert np.max(np.abs(y_batch - y)) <= 1e-9
    assert np.max(its) <= 4
    # l_dot = J y_dot and l_ddot = J y_ddot + bias against 5-point differences of l(t) at 1 kHz (O(dt^4))
    jac = model.jacobian(y)
    l_dot = np.einsum("...ij,...j->...i", jac, yd)
    l_ddot = np.einsum("...ij,...j->...i", jac, ydd) + model.bias(y, yd)
    fd1 = (-l[4:] + 8 * l[3:-1] - 8 * l[1:-3] + l[:-4]) / 12e-3
    fd2 = (-l[4:] + 16 * l[3:-1] - 30 * l[2:-2] + 16 * l[1:-3] - l[:-4]) / 12e-6
    assert np.max(np.abs(fd1 - l_dot[2:-2])) <= 1e-6 * np.max(np.abs(l_dot))
    assert np.max(np.abs(fd2 - l_ddot[2:-2])) <= 1e-4 * np.max(np.abs(l_ddot))  # rounding: 1e-16 m / dt^2


# --- 10. symmetry of mirrored units ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", TWO_DOF)
def test_symmetric_design_jacobian(name: str) -> None:
    jac = models()[name].jacobian(np.zeros(2))
    # the legs mirror each other about the plane normal to the axis whose column flips sign
    flipped = 1 if name == "Body" else 0  # torso: legs at base x = +-20 mm -> roll (base y) column flips
    kept = 1 - flipped
    assert jac[0, kept] == pytest.approx(jac[1, kept], rel=1e-3)
    assert jac[0, flipped] == pytest.approx(-jac[1, flipped], rel=1e-3)


def test_left_right_instances() -> None:
    ms = models()
    rng = np.random.default_rng(2)
    y = rng.uniform(-0.8, 0.8, size=(1000, 2))
    # LRAnkle is LLAnkle mirrored in its x-z plane with the legs swapped: roll flips, pitch stays
    l_left = ms["LLAnkle"].inverse(y * [-1.0, 1.0])
    np.testing.assert_allclose(ms["LRAnkle"].inverse(y), l_left[:, ::-1], rtol=0, atol=1e-15)
    # and LLAnkle itself is symmetric to micrometres (the URDF's rod ends differ by 5 um between the legs)
    np.testing.assert_allclose(ms["LLAnkle"].inverse(y), l_left[:, ::-1], rtol=0, atol=1e-5)
    # copies: the public right-side files have the left side's numbers (geometry.yaml)
    for left, right in (("LLHip3", "LRHip3"), ("LLKnee", "LRKnee"), ("ALWrist", "ARWrist")):
        yy = y[:, : ms[left].dof]
        np.testing.assert_array_equal(ms[left].inverse(yy), ms[right].inverse(yy))


# --- sign conventions: the models' y is the tree model's q --------------------------------------------------------


def _placement(tree: dict) -> pin.SE3:
    return pin.SE3(pin.rpy.rpyToMatrix(*tree["rpy"]), np.array(tree["xyz"], dtype=float))


def _tree_lengths(name: str, y: np.ndarray) -> np.ndarray:
    """Actuator lengths from the geometry moved by the pinocchio tree model (independent of the models' code)."""
    g = submechanism_geometry(name)
    model = build_model(free_flyer=False)
    data = model.createData()
    parent = model.getFrameId(g["tree"]["parent"])
    child = model.getFrameId(g["tree"]["child"])
    base = _placement(g["tree"])  # submechanism base frame in the parent link
    joints = [model.joints[model.getJointId(j)].idx_q for j in models()[name].joints]

    def relative(q_joints: np.ndarray) -> pin.SE3:
        q = pin.neutral(model)
        q[joints] = q_joints
        pin.framesForwardKinematics(model, data, q)
        return data.oMf[parent].actInv(data.oMf[child])  # child link in the parent link

    at_zero = relative(np.zeros(len(joints)))

    def to_child(point: list[float]) -> np.ndarray:
        return at_zero.actInv(base.act(np.array(point)))

    def to_child_dir(vector: list[float]) -> np.ndarray:
        return at_zero.rotation.T @ base.rotation @ np.array(vector)

    out = []
    for y_k in y:
        pose = relative(y_k)
        lengths = []
        if g["type"] == "1-RRPR":
            p = base.act(np.array(g["stator_pivot"]))
            lengths.append(np.linalg.norm(pose.act(to_child(g["rod_end"])) - p))
        elif g["type"] == "2-SPU+1U":
            for leg in g["legs"]:
                b = base.act(np.array(leg["base_pivot"]))
                lengths.append(np.linalg.norm(pose.act(to_child(leg["platform_pivot"])) - b))
        else:  # 2-SPRR+1U: distance from s to the crank circle (centre = rod end projected onto the crank axis)
            for leg in g["legs"]:
                s = base.act(np.array(leg["shank_pivot"]))
                a0 = np.array(leg["crank_axis"]) / np.linalg.norm(leg["crank_axis"])
                k0 = np.array(leg["rod_end"])
                c0 = np.array(leg["crank_pivot"]) + ((k0 - leg["crank_pivot"]) @ a0) * a0
                r = np.linalg.norm(k0 - c0)
                c = pose.act(to_child(c0))
                a = pose.rotation @ to_child_dir(a0)
                d = s - c
                alpha = a @ d
                rho = np.linalg.norm(d - alpha * a)
                lengths.append(math.hypot(alpha, rho - r))
        out.append(lengths)
    return np.array(out)


@pytest.mark.parametrize("name", PARALLEL)
def test_tree_model_sign_convention(name: str) -> None:
    model = models()[name]
    lo, hi = rom(model)
    y = np.random.default_rng(4).uniform(lo, hi, size=(40, model.dof))
    tree = _tree_lengths(name, y)
    # same lengths when the tree turns its joints by +q as the model turns y (an axis sign flip moves them by cm)
    np.testing.assert_allclose(model.inverse(y), tree, rtol=0, atol=1e-9)
    flipped = _tree_lengths(name, -y)
    assert np.max(np.abs(model.inverse(y) - flipped)) > 1e-3


def test_joint_axes_are_the_tree_axes() -> None:
    tree = build_model(free_flyer=False)
    data = tree.createData()
    q = pin.neutral(tree)
    pin.framesForwardKinematics(tree, data, q)
    pin.computeJointJacobians(tree, data, q)
    for name in PARALLEL:
        g, model = submechanism_geometry(name), models()[name]
        base = data.oMf[tree.getFrameId(g["tree"]["parent"])].act(_placement(g["tree"]))
        axes = model.joint_axes if model.dof == 2 else [model.axis]
        for joint, axis in zip(model.joints, axes, strict=True):
            joint_id = tree.getJointId(joint)
            column = tree.joints[joint_id].idx_v
            jac = pin.getJointJacobian(tree, data, joint_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            axis_world = jac[3:, column]  # world angular velocity per unit +q
            assert np.linalg.norm(base.rotation @ axis - axis_world) < 1e-5, (name, joint)


def test_length_direction_per_joint() -> None:
    """dl/dq at the zero pose has the signs the public submechanism files give (design 3.1, 5.3, 7.3, 7.4)."""
    signs = {
        "Hip3": [[-1]],  # +q shortens (hip extension; paper ROM sign-flipped, s = -1)
        "Knee": [[+1]],  # +q (flexion) lengthens
        "Ankle": [[-1, -1], [+1, -1]],  # J(0) = [[-39.30, -74.15], [39.30, -74.15]] mm/rad (roll, pitch)
        "Body": [[+1, -1], [+1, +1]],  # J(0) = [[87.30, -69.11], [87.30, 69.11]] (pitch, roll)
        "Wrist": [[+1, -1], [-1, -1]],  # J(0) = [[34.56, -35.83], [-34.56, -35.83]] (yaw, pitch)
    }
    for name in PARALLEL:
        jac = models()[name].jacobian(np.zeros(models()[name].dof))
        np.testing.assert_array_equal(np.sign(jac), signs[unit_key(name)], err_msg=name)
    # and the stroke ends sit at the ROM ends the paper's table implies: Hip3 431 mm at -72 deg (flexion)
    hip = models()["LLHip3"]
    assert hip.inverse(np.radians([-72.0]))[0] == pytest.approx(0.4305, abs=1e-3)
    assert hip.inverse(np.radians([16.4]))[0] == pytest.approx(0.2718, abs=1e-3)  # the URDF ROM end, 272 mm


# --- linear models ---------------------------------------------------------------------------------------------------


def test_serial_pass_through() -> None:
    limits = joint_limits()
    for model in build_submechanisms():
        if model.kind != "serial":
            continue
        j = JOINT_INDEX[model.joints[0]]
        assert model.limits.length_min[0] == limits.position_lower[j]
        assert model.limits.length_max[0] == limits.position_upper[j]
        assert model.limits.velocity_max[0] == limits.velocity_max[j]
        assert model.limits.force_max[0] == limits.torque_max[j]
        y = np.array([[0.3], [-1.2]])
        np.testing.assert_array_equal(model.inverse(y), y)
        np.testing.assert_array_equal(model.forward(y), y)
        np.testing.assert_array_equal(model.jacobian(y), np.ones((2, 1, 1)))
        np.testing.assert_array_equal(model.bias(y, y), 0.0)
        np.testing.assert_array_equal(model.forces(y, y), y)
        np.testing.assert_array_equal(model.torques(y[0], np.array([2.0])), [2.0])


def test_head_transmission() -> None:
    head = models()["Head"]
    assert head.joints == ("HeadPitch", "HeadRoll", "HeadYaw")
    np.testing.assert_array_equal(head.jacobian(np.zeros(3)), HEAD_TRANSMISSION)
    y = np.array([0.1, -0.2, 0.5])
    np.testing.assert_allclose(head.inverse(y), [0.1 - 0.2, 0.1 + 0.2, 0.5])  # Act1 = P + R, Act2 = P - R, Act3 = Y
    np.testing.assert_allclose(head.forward(head.inverse(y)), y)
    tau = np.array([3.0, 1.0, -2.0])
    f = head.forces(y, tau)
    np.testing.assert_allclose(head.torques(y, f), tau)
    np.testing.assert_allclose(f @ head.jacobian(y) @ np.ones(3), tau @ np.ones(3))  # power: f . (T yd) = tau . yd
    # actuator limits = the joint limits mapped through T (pitch -20..15 deg, roll +-25 deg, 9.8 Nm, 8.06 rad/s)
    limits = joint_limits()
    idx = [JOINT_INDEX[j] for j in head.joints]
    lo, hi = limits.position_lower[idx], limits.position_upper[idx]
    np.testing.assert_allclose(head.limits.length_min, [lo[0] + lo[1], lo[0] - hi[1], lo[2]])
    np.testing.assert_allclose(head.limits.length_max, [hi[0] + hi[1], hi[0] - lo[1], hi[2]])
    np.testing.assert_allclose(head.limits.force_max, [9.8, 9.8, 4.9])
    corners = np.array(np.meshgrid(*zip(lo, hi, strict=True), indexing="ij")).reshape(3, -1).T
    images = head.inverse(corners)
    assert np.all((images >= head.limits.length_min - 1e-12) & (images <= head.limits.length_max + 1e-12))


def test_geometry_file_cites_its_values() -> None:
    raw = load_geometry()
    assert set(raw["actuator_types"]) == {"hip3", "knee", "ankle", "torso", "wrist"}
    for name in PARALLEL:
        g = submechanism_geometry(name)
        assert g["type"] == models()[name].kind
        assert {"parent", "child", "xyz", "rpy"} <= set(g["tree"])
    assert submechanism_geometry("LRAnkle")["legs"][0]["shank_pivot"][1] > 0  # Act1 at +y as in LRAnkle.urdf


# --- fused maps: to_actuator_space / to_joint_space equal the separate methods --------------------------------------

FUSED = (*PARALLEL, "Head", "BodyYaw")
ACTUATOR_COMBOS = [  # which of (yd, ydd, tau) are given
    (False, False, False),
    (True, False, False),
    (True, True, False),
    (False, False, True),
    (True, False, True),
    (True, True, True),
    (False, True, False),  # ydd without yd: no l_ddot (it needs the bias)
]
JOINT_COMBOS = [(False, False), (True, False), (False, True), (True, True)]  # which of (ld, f) are given


def _fused_samples(name: str, n: int = 200) -> tuple[SubmechanismModel, np.ndarray, ...]:
    model = models()[name]
    y = feasible(name)[0][:n] if name in PARALLEL else np.random.default_rng(8).uniform(-0.5, 0.5, (n, model.dof))
    rng = np.random.default_rng(zlib.crc32(name.encode()) + 1)
    yd, ydd, tau = rng.uniform(-3, 3, y.shape), rng.uniform(-30, 30, y.shape), rng.normal(scale=50.0, size=y.shape)
    return model, y, yd, ydd, tau


def _matvec(jac: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.einsum("...ij,...j->...i", jac, x)


def _check_actuator_space(model: SubmechanismModel, inputs: tuple, got: tuple) -> None:
    """The fused answer against inverse, jacobian, bias and forces: l, f and the bias bit for bit."""
    y, yd, ydd, tau = inputs
    l, ld, ldd, f = got
    np.testing.assert_array_equal(l, model.inverse(y))
    assert (ld is None) == (yd is None)
    assert (ldd is None) == (yd is None or ydd is None)
    assert (f is None) == (tau is None)
    if yd is not None:
        jac = model.jacobian(y)
        scale = np.max(np.abs(jac)) * np.max(np.abs(yd))
        np.testing.assert_allclose(ld, _matvec(jac, yd), rtol=1e-13, atol=1e-15 * scale)
        if ydd is not None:
            want = _matvec(jac, ydd) + model.bias(y, yd)
            np.testing.assert_allclose(ldd, want, rtol=1e-12, atol=1e-14 * np.max(np.abs(want)))
            # at y_ddot = 0 the fused l_ddot is exactly the bias
            at_rest = model.to_actuator_space(y, yd, np.zeros_like(yd))[2]
            np.testing.assert_array_equal(at_rest, model.bias(y, yd))
    if tau is not None:
        np.testing.assert_array_equal(f, model.forces(y, tau))


@pytest.mark.parametrize("name", FUSED)
@pytest.mark.parametrize("combo", ACTUATOR_COMBOS)
def test_fused_to_actuator_space_equals_separate_methods(name: str, combo: tuple[bool, bool, bool]) -> None:
    model, y, yd, ydd, tau = _fused_samples(name)
    yd, ydd, tau = (x if given else None for x, given in zip((yd, ydd, tau), combo, strict=True))
    batch = model.to_actuator_space(y, yd, ydd, tau)
    _check_actuator_space(model, (y, yd, ydd, tau), batch)
    for k in range(0, len(y), 20):  # single samples: a batch of one
        pick = [None if x is None else x[k] for x in (yd, ydd, tau)]
        single = model.to_actuator_space(y[k], *pick)
        _check_actuator_space(model, (y[k], *pick), single)
        for got, want in zip(single, batch, strict=True):
            if want is not None:
                assert isinstance(got, np.ndarray)
                assert got.shape == (model.dof,)
                np.testing.assert_allclose(got, want[k], rtol=1e-12, atol=1e-14 * max(1.0, float(np.max(np.abs(want)))))


@pytest.mark.parametrize("name", FUSED)
def test_fused_to_actuator_space_any_leading_shape(name: str) -> None:
    model, y, yd, ydd, tau = _fused_samples(name, 24)
    shape = (2, 3, 4, model.dof)
    got = model.to_actuator_space(y.reshape(shape), yd.reshape(shape), ydd.reshape(shape), tau.reshape(shape))
    flat = model.to_actuator_space(y, yd, ydd, tau)
    for a, b in zip(got, flat, strict=True):
        assert a.shape == shape
        np.testing.assert_array_equal(a.reshape(b.shape), b)
    # one velocity for every pose broadcasts as if given for each
    every = model.to_actuator_space(y, np.broadcast_to(yd[0], y.shape), np.broadcast_to(ydd[0], y.shape), tau)
    for a, b in zip(model.to_actuator_space(y, yd[0], ydd[0], tau), every, strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(KinematicsError, match=name):
        model.to_actuator_space(np.zeros((3, model.dof + 1)))


def _check_joint_space(model: SubmechanismModel, inputs: tuple, got: tuple) -> None:
    """The fused answer against forward, jacobian (at the returned y) and torques: y and tau bit for bit."""
    l, ld, f, guess = inputs
    y, yd, tau = got
    np.testing.assert_array_equal(y, model.forward(l, guess))
    assert (yd is None) == (ld is None)
    assert (tau is None) == (f is None)
    if ld is not None:
        jac = model.jacobian(y)
        want = np.linalg.solve(jac, ld[..., None])[..., 0]
        np.testing.assert_allclose(yd, want, rtol=1e-12, atol=1e-13 * np.max(np.abs(want)))
        np.testing.assert_allclose(_matvec(jac, yd), ld, rtol=1e-12, atol=1e-14 * np.max(np.abs(ld)))
    if f is not None:
        np.testing.assert_array_equal(tau, model.torques(y, f))  # J evaluated at exactly the returned y


@pytest.mark.parametrize("name", FUSED)
@pytest.mark.parametrize("combo", JOINT_COMBOS)
def test_fused_to_joint_space_equals_separate_methods(name: str, combo: tuple[bool, bool]) -> None:
    model, y, yd, _, tau = _fused_samples(name)
    l = model.inverse(y)
    ld, f = (x if given else None for x, given in zip((_matvec(model.jacobian(y), yd), tau), combo, strict=True))
    for guess in (None, y + 1e-3):  # cold and warm start
        batch = model.to_joint_space(l, ld, f, guess)
        _check_joint_space(model, (l, ld, f, guess), batch)
        for k in range(0, len(y), 20):
            pick = [None if x is None else x[k] for x in (ld, f, guess)]
            single = model.to_joint_space(l[k], *pick)
            _check_joint_space(model, (l[k], *pick), single)
            np.testing.assert_allclose(single[0], y[k], rtol=0, atol=1e-9)


@pytest.mark.parametrize("name", TWO_DOF)
def test_fused_to_joint_space_jacobian_at_the_wrapped_pose(name: str) -> None:
    """A warm start one turn away converges to y + 2 pi, returned wrapped: J (and tau) belong to the wrapped y."""
    model, y, yd, _, tau = _fused_samples(name, 20)
    l = model.inverse(y)
    ld = _matvec(model.jacobian(y), yd)
    for turn in (np.array([2 * np.pi, 0.0]), np.array([0.0, -2 * np.pi])):
        batch = model.to_joint_space(l, ld, tau, y + turn)
        assert np.all(np.abs(batch[0]) <= np.pi)
        _check_joint_space(model, (l, ld, tau, y + turn), batch)
        for k in range(len(y)):
            single = model.to_joint_space(l[k], ld[k], tau[k], y[k] + turn)
            _check_joint_space(model, (l[k], ld[k], tau[k], y[k] + turn), single)


@pytest.mark.parametrize("name", TWO_DOF)
def test_fused_singularity_refusal_two_dof(name: str) -> None:
    model = models()[name]
    y_singular = _singular_pose(model)
    tau, yd = np.array([10.0, -5.0]), np.array([0.2, 0.1])
    with pytest.raises(SingularityError) as separate:
        model.forces(y_singular, tau)
    with pytest.raises(SingularityError) as fused:
        model.to_actuator_space(y_singular, yd, yd, tau)
    assert str(fused.value) == str(separate.value)
    poses, taus = np.stack([np.zeros(2), y_singular]), np.stack([tau, tau])
    with pytest.raises(SingularityError) as separate_batch:
        model.forces(poses, taus)
    with pytest.raises(SingularityError) as fused_batch:  # one singular sample refuses the whole call
        model.to_actuator_space(poses, None, None, taus)
    assert str(fused_batch.value) == str(separate_batch.value)
    with pytest.raises(SingularityError, match=name):  # a tiny max_condition refuses even the zero pose
        model.to_actuator_space(np.zeros(2), tau=tau, max_condition=1.0 - 1e-12)
    l, ld, ldd, f = model.to_actuator_space(y_singular, yd, yd)  # no forces asked: no refusal
    assert f is None
    assert np.all(np.isfinite(l))
    assert ld is not None
    assert ldd is not None


@pytest.mark.parametrize("name", ["LLHip3", "LRKnee"])
def test_fused_singularity_refusal_lambda(name: str) -> None:
    model = models()[name]
    assert isinstance(model, Lambda1RRPR)
    for y_singular in (np.array([-model.phi0 + 1e-9]), np.array([-model.phi0])):  # J tiny, J zero
        with pytest.raises(SingularityError) as separate, np.errstate(divide="ignore"):
            model.forces(y_singular, np.array([100.0]))
        for call in (
            lambda y=y_singular: model.to_actuator_space(y, tau=np.array([100.0])),
            lambda y=y_singular: model.to_actuator_space(y, np.array([1.0]), np.array([0.0]), np.array([100.0])),
        ):
            with pytest.raises(SingularityError) as fused:
                call()
            assert str(fused.value) == str(separate.value)
    poses, taus = np.array([[0.0], [-model.phi0 + 1e-9]]), np.array([[1.0], [1.0]])
    with pytest.raises(SingularityError) as separate_batch:
        model.forces(poses, taus)
    with pytest.raises(SingularityError) as fused_batch:
        model.to_actuator_space(poses, taus, None, taus)
    assert str(fused_batch.value) == str(separate_batch.value)


def test_fused_linear_refusal_and_errors() -> None:
    head = models()["Head"]
    with pytest.raises(SingularityError) as separate:
        head.forces(np.zeros(3), np.ones(3), max_condition=1.2)  # cond(T) = sqrt(2)
    for call in (
        lambda: head.to_actuator_space(np.zeros(3), tau=np.ones(3), max_condition=1.2),
        lambda: head.to_actuator_space(np.zeros((4, 3)), tau=np.ones((4, 3)), max_condition=1.2),
    ):
        with pytest.raises(SingularityError) as fused:
            call()
        assert str(fused.value) == str(separate.value)
    assert head.to_actuator_space(np.zeros(3), max_condition=1.2)[3] is None  # no forces asked: no refusal


@pytest.mark.parametrize("name", ["LLHip3", *TWO_DOF])
def test_fused_forward_errors(name: str) -> None:
    model = models()[name]
    bad = np.full(model.dof, 0.9)
    with pytest.raises(ForwardKinematicsError) as separate:
        model.forward(bad)
    with pytest.raises(ForwardKinematicsError) as fused:
        model.to_joint_space(bad, bad, bad)
    assert str(fused.value) == str(separate.value)
    with pytest.raises(ForwardKinematicsError, match=r"1 of 2 sample"):
        model.to_joint_space(np.stack([model.l0, bad]), np.zeros((2, model.dof)))


def test_mapper_is_the_models_maps() -> None:
    """RobotMapper's whole-robot table gives each unit's own answer, one sample or a batch."""
    from rh5_hyrodyn_mapper.mapping import RobotMapper
    from rh5_msgs_py.names import ACTUATOR_INDEX, NUM_JOINTS

    mapper = RobotMapper()
    rng = np.random.default_rng(12)
    q = rng.uniform(-0.1, 0.1, (5, NUM_JOINTS))
    v, a, tau = rng.normal(size=q.shape), rng.normal(size=q.shape), rng.normal(scale=20.0, size=q.shape)
    batch = mapper.to_actuators(q, v, a, tau)
    back_batch = mapper.to_joints(batch.position, batch.velocity, batch.effort, q_guess=q)
    for k in range(len(q)):
        single = mapper.to_actuators(q[k], v[k], a[k], tau[k])
        back = mapper.to_joints(single.position, single.velocity, single.effort, q_guess=q[k])
        for model in build_submechanisms():
            jj = [JOINT_INDEX[j] for j in model.joints]
            aa = [ACTUATOR_INDEX[x] for x in model.actuators]
            fused = model.to_actuator_space(q[k, jj], v[k, jj], a[k, jj], tau[k, jj])
            for got, want in zip(single, fused, strict=True):
                np.testing.assert_array_equal(got[aa], want)
            joints = model.to_joint_space(single.position[aa], single.velocity[aa], single.effort[aa], q[k, jj])
            for got, want in zip((back.position, back.velocity, back.effort), joints, strict=True):
                np.testing.assert_array_equal(got[jj], want)
        for got, want in zip(single, batch, strict=True):
            np.testing.assert_allclose(got, want[k], rtol=1e-12, atol=1e-12)
        for got, want in zip(back, back_batch, strict=True):
            if want is not None:
                np.testing.assert_allclose(got, want[k], rtol=1e-12, atol=1e-12)
        partial = mapper.to_actuators(q[k], tau=tau[k])
        assert partial.velocity is None
        assert partial.acceleration is None
        np.testing.assert_array_equal(partial.effort, single.effort)
        cold = mapper.to_joints(single.position, f=single.effort)
        assert cold.velocity is None
        np.testing.assert_allclose(cold.position, q[k], rtol=0, atol=1e-9)
