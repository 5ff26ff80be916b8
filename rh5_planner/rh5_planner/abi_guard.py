"""Numerical guard of the Crocoddyl/Pinocchio pairing, run at planner start-up and in CI.

libcrocoddyl 3.2.1 is compiled against Pinocchio 4.0.0 headers; with Pinocchio 4.1.0 the
``pinocchio::Model`` layout differs, and Crocoddyl silently computes every robot without
gravity and reads frames out of bounds (design/crocoddyl_wheels.md). Nothing at import
time notices, so this compares Crocoddyl's own free dynamics and 6D contact Jacobian with
Pinocchio's on the RH5 model. Run it in a child process (``python -m
rh5_planner.abi_guard``): a broken pairing may crash instead of answering.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

KNOWN_GOOD_PAIRS = {("3.2.1", "4.0.0")}
TOLERANCE = 1e-9


@dataclass(frozen=True)
class GuardResult:
    """Largest deviations found, and the versions that produced them."""

    crocoddyl_version: str
    pinocchio_version: str
    dynamics_error: float
    contact_jacobian_error: float

    @property
    def ok(self) -> bool:
        """Whether Crocoddyl agrees with Pinocchio to numerical precision."""
        return self.dynamics_error < TOLERANCE and self.contact_jacobian_error < TOLERANCE

    @property
    def known_good(self) -> bool:
        """Whether the version pair is one the project has verified."""
        return (self.crocoddyl_version, self.pinocchio_version) in KNOWN_GOOD_PAIRS


def check_pairing(samples: int = 5, seed: int = 0) -> GuardResult:
    """Compare free forward dynamics and a foot's 6D contact Jacobian on random RH5 states."""
    import crocoddyl  # noqa: PLC0415 (crocoddyl must be imported before anything linking pinocchio extensions)
    import pinocchio  # noqa: PLC0415

    from rh5_hyrodyn_mapper.model import build_model  # noqa: PLC0415
    from rh5_msgs_py.names import FOOT_FRAMES  # noqa: PLC0415

    model = build_model(free_flyer=True)
    data = model.createData()
    state = crocoddyl.StateMultibody(model)
    actuation = crocoddyl.ActuationModelFloatingBase(state)
    costs = crocoddyl.CostModelSum(state, actuation.nu)
    free = crocoddyl.DifferentialActionModelFreeFwdDynamics(state, actuation, costs)
    free_data = free.createData()
    foot = model.getFrameId(FOOT_FRAMES["left"])
    contact = crocoddyl.ContactModel6D(
        state, foot, pinocchio.SE3.Identity(), pinocchio.ReferenceFrame.LOCAL, actuation.nu, np.zeros(2)
    )
    contact_data = contact.createData(data)
    rng = np.random.default_rng(seed)
    dyn_err = jac_err = 0.0
    for _ in range(samples):
        q = pinocchio.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
        v = rng.uniform(-1, 1, model.nv)
        u = rng.uniform(-10, 10, actuation.nu)
        free.calc(free_data, np.concatenate([q, v]), u)
        tau = np.concatenate([np.zeros(6), u])
        reference = pinocchio.aba(model, model.createData(), q, v, tau)
        dyn_err = max(dyn_err, float(np.max(np.abs(free_data.xout - reference)) / (1 + np.max(np.abs(reference)))))
        pinocchio.forwardKinematics(model, data, q, v)
        pinocchio.computeJointJacobians(model, data, q)
        pinocchio.updateFramePlacements(model, data)
        contact.calc(contact_data, np.concatenate([q, v]))
        jacobian = pinocchio.getFrameJacobian(model, data, foot, pinocchio.ReferenceFrame.LOCAL)
        jac_err = max(jac_err, float(np.max(np.abs(contact_data.Jc - jacobian))))
    return GuardResult(crocoddyl.__version__, pinocchio.__version__, dyn_err, jac_err)


def main() -> int:
    """Print the guard's verdict; exit 0 when the pairing is sound, 1 when it is not."""
    result = check_pairing()
    verdict = "OK" if result.ok else "BROKEN"
    print(
        f"crocoddyl {result.crocoddyl_version} + pinocchio {result.pinocchio_version}: {verdict} "
        f"(dynamics error {result.dynamics_error:.2e}, contact Jacobian error {result.contact_jacobian_error:.2e}"
        f"{'' if result.known_good else '; not a verified version pair'})"
    )
    return 0 if result.ok else 1


if __name__ == "__main__":
    sys.exit(main())
