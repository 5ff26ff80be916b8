"""The action model of every knot: contact dynamics between touch-downs, impulse dynamics at them.

* Dynamics: floating-base contact dynamics with rigid 6D sole contacts (``ContactModel6D`` on
  ``LLFoot_Sole``/``LRFoot_Sole``, LOCAL frame, Baumgarte gains from costs.yaml) in
  ``DifferentialActionModelContactFwdDynamics``, integrated by ``IntegratedActionModelEuler`` (symplectic
  Euler, one knot per ``motion.dt``). Every touch-down is an ``ActionModelImpulseFwdDynamics`` node
  (``ImpulseModel6D`` on the landing soles, zero restitution) of zero duration.
* Torque limits are the hard box of Box-FDDP: every action model's ``u_lb``/``u_ub`` are
  -/+ ``joint_limits().torque_max`` (the upper ends of the paper's configuration-dependent ranges).
"""

from __future__ import annotations

import crocoddyl
import numpy as np
import pinocchio as pin

from rh5_msgs_py.names import FOOT_FRAMES

from ..motions import SIDES, KnotSpec
from .costs import CostTerms, knot_costs

__all__ = ["contact_model", "impulse_model"]


def contact_model(ct: CostTerms, spec: KnotSpec, *, dt: float, terminal: bool = False) -> crocoddyl.ActionModelAbstract:
    """A running (or, with ``terminal``, the terminal) knot: contact dynamics on the soles in contact, Euler over
    ``dt``, the torque box of Box-FDDP."""
    robot = ct.robot
    nu = robot.actuation.nu
    contacts = crocoddyl.ContactModelMultiple(robot.state, nu)
    gains = np.asarray(ct.config["contact_stability"]["baumgarte_gains"], dtype=float)
    for side in SIDES:
        if spec.in_contact(side):
            placement = pin.SE3(ct.foot_rotations[side], np.asarray(spec.feet[side]))
            contact = crocoddyl.ContactModel6D(
                robot.state, robot.foot_ids[side], placement, pin.ReferenceFrame.LOCAL, nu, gains
            )
            contacts.addContact(f"{FOOT_FRAMES[side]}_contact", contact)
    costs = knot_costs(ct, spec, nu, terminal=terminal)
    dam = crocoddyl.DifferentialActionModelContactFwdDynamics(robot.state, robot.actuation, contacts, costs, 0.0, True)
    iam = crocoddyl.IntegratedActionModelEuler(dam, 0.0 if terminal else dt)
    iam.u_lb = -robot.tau_max
    iam.u_ub = robot.tau_max
    return iam


def impulse_model(ct: CostTerms, spec: KnotSpec) -> crocoddyl.ActionModelAbstract:
    """A touch-down knot of zero duration: the impulse of the soles in contact after the impact."""
    robot = ct.robot
    impulses = crocoddyl.ImpulseModelMultiple(robot.state)
    for side in SIDES:
        if spec.in_contact(side):
            impulse = crocoddyl.ImpulseModel6D(robot.state, robot.foot_ids[side], pin.ReferenceFrame.LOCAL)
            impulses.addImpulse(f"{FOOT_FRAMES[side]}_impulse", impulse)
    costs = knot_costs(ct, spec, 0)
    return crocoddyl.ActionModelImpulseFwdDynamics(robot.state, impulses, costs, 0.0, 0.0, True)
