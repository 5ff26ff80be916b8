"""geometry_msgs/WrenchStamped <-> a 6-vector (force then torque)."""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import WrenchStamped
from numpy.typing import ArrayLike

from rh5_msgs_py.array_types import FloatArray

from .joint_state import _vector
from .times import _set_stamp


def wrench_to_msg(
    wrench6: ArrayLike, frame_id: str = "", stamp_ns: int = 0, *, msg: WrenchStamped | None = None
) -> WrenchStamped:
    """geometry_msgs/WrenchStamped from (6,) = force xyz [N], torque xyz [Nm]; fills ``msg`` if given."""
    fx, fy, fz, tx, ty, tz = _vector(wrench6, 6, "wrench").tolist()
    out = WrenchStamped() if msg is None else msg
    _set_stamp(out.header, stamp_ns)
    out.header.frame_id = frame_id
    force, torque = out.wrench.force, out.wrench.torque
    force.x, force.y, force.z = fx, fy, fz
    torque.x, torque.y, torque.z = tx, ty, tz
    return out


def wrench_from_msg(msg: WrenchStamped) -> FloatArray:
    """(6,) array from a WrenchStamped: force xyz, torque xyz."""
    f, t = msg.wrench.force, msg.wrench.torque
    return np.array((f.x, f.y, f.z, t.x, t.y, t.z), dtype=np.float64)
