"""The planner's parameter spec offers exactly the paper's motions and sane solver bounds."""

from __future__ import annotations

from rh5_msgs_py.parameters import load_spec
from rh5_planner.abi_guard import TOLERANCE, GuardResult

PAPER_MOTIONS = {
    "walk_with_5kg_weights",
    "fast_walk_1m_s",
    "squat_with_5kg_weights",
    "vertical_jump_1cm",
    "vertical_jump_10cm",
    "obstacle_jumps",
    "one_leg_balancing",
    "static_stepping",
    "fast_squats",
}


def test_motion_choices_are_the_nine_motions() -> None:
    motion = {s.name: s for s in load_spec("rh5_planner", "params/planner.yaml")}["motion"]
    assert set(motion.choices) == PAPER_MOTIONS
    assert "not one of" in motion.check("moonwalk")


def test_guard_result_verdicts() -> None:
    good = GuardResult("3.2.1", "4.0.0", 0.0, TOLERANCE / 10)
    assert good.ok
    assert good.known_good
    broken = GuardResult("3.2.1", "4.1.0", 9.81, 0.0)
    assert not broken.ok
    assert not broken.known_good
