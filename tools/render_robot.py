"""Render RH5 from the URDF's visuals at the walk's first pose, offscreen (PyBullet's TinyRenderer, no display).

    .venv/bin/python tools/render_robot.py [--trajectory out/trajectories/walk_with_5kg_weights-*.npz]
                                           [--output docs/rh5_walk_first_pose.png]

The pose is the first knot of a trajectory file when one is given, else the walk's initial pose as the planner
builds it (rh5_planner.ocp.nominal_configuration with the walk's knee bend). Two views side by side: front
three-quarter (the robot's left in red, right in blue) and its right side.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
VIEWS = ((35.0, -12.0), (0.0, -5.0))
"""Camera yaw and pitch [deg] of each view."""


def first_pose(trajectory: Path | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Base position, base quaternion (x, y, z, w) and the 32 joint angles (JOINT_NAMES order)."""
    if trajectory is not None:
        from rh5_msgs_py.trajectory_file import load_trajectory  # noqa: PLC0415

        data = load_trajectory(trajectory)
        return data.base_positions()[0], data.base_quaternions_xyzw()[0], data.joint_positions()[0]
    from rh5_hyrodyn_mapper.model import build_model, q_index  # noqa: PLC0415
    from rh5_planner.motions import get_motion  # noqa: PLC0415
    from rh5_planner.ocp import nominal_configuration  # noqa: PLC0415

    model = build_model()
    q = nominal_configuration(model, get_motion("walk_with_5kg_weights").knee_bend_rad)
    return q[:3], q[3:7], q[q_index(model)]


def render(base: np.ndarray, orientation: np.ndarray, joints: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """RGB images of every view, side by side."""
    import pybullet as pb  # noqa: PLC0415

    from rh5_hyrodyn_mapper.model import generate_urdf  # noqa: PLC0415
    from rh5_msgs_py.names import JOINT_NAMES  # noqa: PLC0415

    client = pb.connect(pb.DIRECT)
    try:
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "rh5.urdf"
            path.write_text(generate_urdf(visuals=True), encoding="utf-8")
            robot = pb.loadURDF(str(path), physicsClientId=client)
        pb.resetBasePositionAndOrientation(robot, base.tolist(), orientation.tolist(), physicsClientId=client)
        index = {
            pb.getJointInfo(robot, i, physicsClientId=client)[1].decode(): i
            for i in range(pb.getNumJoints(robot, physicsClientId=client))
        }
        for name, angle in zip(JOINT_NAMES, joints, strict=True):
            pb.resetJointState(robot, index[name], float(angle), physicsClientId=client)
        plane = pb.createVisualShape(
            pb.GEOM_BOX, halfExtents=[1.2, 1.2, 0.002], rgbaColor=[0.9, 0.9, 0.85, 1], physicsClientId=client
        )
        pb.createMultiBody(0, -1, plane, [base[0], base[1], -0.002], physicsClientId=client)
        width, height = size
        images = []
        for yaw, pitch in VIEWS:
            view = pb.computeViewMatrixFromYawPitchRoll(
                [base[0], base[1], 0.95], 2.6, yaw, pitch, 0, 2, physicsClientId=client
            )
            projection = pb.computeProjectionMatrixFOV(45.0, width / height, 0.1, 10.0, physicsClientId=client)
            _, _, rgba, _, _ = pb.getCameraImage(
                width,
                height,
                view,
                projection,
                renderer=pb.ER_TINY_RENDERER,
                lightDirection=[1, 1, 2],
                physicsClientId=client,
            )
            images.append(np.reshape(np.asarray(rgba, dtype=np.uint8), (height, width, 4))[:, :, :3])
        return np.concatenate(images, axis=1)
    finally:
        pb.disconnect(physicsClientId=client)


def main(argv: list[str] | None = None) -> int:
    """Write the PNG; print where."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trajectory", type=Path, help="trajectory file whose first knot is rendered")
    parser.add_argument("--output", type=Path, default=REPO / "docs" / "rh5_walk_first_pose.png")
    parser.add_argument("--size", type=int, nargs=2, default=(480, 640), metavar=("WIDTH", "HEIGHT"))
    args = parser.parse_args(argv)
    import matplotlib.image  # noqa: PLC0415

    image = render(*first_pose(args.trajectory), tuple(args.size))
    args.output.parent.mkdir(parents=True, exist_ok=True)
    matplotlib.image.imsave(args.output, image)
    print(f"render_robot: wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
