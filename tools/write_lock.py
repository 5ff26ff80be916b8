"""Print a pip constraints file pinning every distribution of a venv (for ``make lock``).

The ROS wheels also register their inner message packages (``std_msgs``, ``rclpy``...)
as distributions; those are not installable names on PyPI, so they are left out.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

BUNDLED_BY_ROS_WHEELS = ("_msgs", "_srvs", "_interfaces", "rclpy", "rcutils", "rmw_dds_common", "rosidl_", "rcutils")
TOOLING = ("pip", "setuptools")


def main(venv: str) -> None:
    frozen = subprocess.run(
        [str(Path(venv) / "bin" / "python"), "-m", "pip", "freeze", "--all"], check=True, capture_output=True, text=True
    ).stdout.split()
    keep = []
    for line in frozen:
        name = line.split("==")[0]
        if (
            name in TOOLING
            or ("_" in name and any(tag in name for tag in BUNDLED_BY_ROS_WHEELS))
            or name in ("rclpy", "rcutils")
        ):
            continue
        keep.append(line)
    print("# Full lock of the development/runtime set (pip constraints). Regenerate with 'make lock'.")
    print("# crocoddyl 3.2.1 is built against pinocchio 4.0.0: keep pin/libpinocchio at 4.0.0")
    print("# (../shared/design/crocoddyl_wheels.md; guarded by tests/test_crocoddyl_pinocchio_abi.py).")
    print("\n".join(sorted(keep, key=str.lower)))


if __name__ == "__main__":
    main(sys.argv[1])
