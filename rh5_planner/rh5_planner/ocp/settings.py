"""Box-FDDP settings of one solve (:class:`SolverSettings`) and the signature of its progress callback."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["ProgressCallback", "SolverSettings"]

ProgressCallback = Callable[[int, float, float], None]
"""``callback(iteration, cost, stop)`` called after every Box-FDDP iteration."""


@dataclass(frozen=True)
class SolverSettings:
    """Box-FDDP settings: iteration cap, stop threshold, threads of the derivative pass, progress callback."""

    max_iterations: int = 200
    stop_threshold: float = 1e-7
    nthreads: int = 2
    callback: ProgressCallback | None = None
    verbose: bool = False
    cost_config: Mapping[str, Any] | None = None
    interpolate_guess: bool = True
    continuation: bool = True
    """Solve the stages of costs.yaml ``continuation`` (cost terms faded in) before the final problem."""
    cost_tolerance: float = 1e-7
    """Also stop (converged, reason ``cost_stalled``) once the trajectory is feasible and the cost changed by less
    than this fraction over the last ``stall_iterations`` iterations, all full steps; 0 disables it."""
    stall_iterations: int = 5
    guess_regularization: float = 1e-2
    """Box-FDDP's initial regularisation of the first stage, which starts from the built guess (kinematic, with
    dynamic gaps): Crocoddyl's own 1e-9 trusts it like a converged solution, and fast_walk_1m_s then spent 7
    iterations of 10 rejected line-search steps raising it; from 1e-2 it needs 34 iterations instead of 52,
    vertical_jump_10cm 99 instead of 109, obstacle_jumps 68 instead of 72 (same optima, the others within 2)."""
    stage_regularization: float = 1e-4
    """The same for every later continuation stage. Such a stage starts from the previous stage's optimum, closer
    but no Newton-close guess once its cost terms have stiffened: from 1e-9 the walk's final stage spent 7
    iterations of rejected steps; from 1e-4 it needs 41 iterations instead of 46 and vertical_jump_10cm 109 instead
    of 126 (1e-2 here: 43 and 119)."""
