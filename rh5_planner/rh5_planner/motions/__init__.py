"""The motion library: every motion the planner solves, its parameters and its contact sequence.

One frozen dataclass per motion kind holds the parameters (the paper's table "Characteristics and applied
optimization constraints" and its three hardware experiments); :data:`MOTIONS` holds the nine named
motions with the paper's values. ``motion.with_overrides({"length_m": 0.4})`` returns a validated copy.

``motion.knots(reference)`` turns the parameters into the contact sequence the problem builder
(:mod:`rh5_planner.ocp`) consumes: one :class:`KnotSpec` per shooting node, saying which feet are in
contact, where every sole should be (swing trajectories, touch-down placements) and, where the motion
tracks it, where the CoM should be. Impulse knots (touch-down) have zero duration. The package is pure
numpy, so motions can be listed and validated without Crocoddyl.

One module per job: :mod:`.spec` (what every motion is: :class:`MotionSpec`, :class:`KnotSpec`, conventions and knot
timing), :mod:`.validation` (:class:`MotionError` and the parameter checks), one module per motion family
(:mod:`.walk`, :mod:`.squat`, :mod:`.jump`, :mod:`.balance`) and :mod:`.catalogue` (the named motions, the paper's
settings, which are verified). This package re-exports their public names.
"""

from __future__ import annotations

from .balance import BalanceMotion
from .catalogue import MOTIONS, PAPER_SETTINGS, VERIFIED_MOTIONS, get_motion
from .jump import JumpMotion
from .spec import COST_TERMS, SIDES, KnotSpec, MotionSpec, Reference
from .squat import SquatMotion
from .validation import MotionError
from .walk import WalkMotion

__all__ = [
    "COST_TERMS",
    "MOTIONS",
    "PAPER_SETTINGS",
    "SIDES",
    "VERIFIED_MOTIONS",
    "BalanceMotion",
    "JumpMotion",
    "KnotSpec",
    "MotionError",
    "MotionSpec",
    "Reference",
    "SquatMotion",
    "WalkMotion",
    "get_motion",
]
