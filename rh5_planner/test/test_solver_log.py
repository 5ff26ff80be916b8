"""The solver log's typed record reads and writes the JSON object trajectory files have always held."""

from __future__ import annotations

import json
import math

from rh5_planner.solver_log import ActuatorLimitLog, RefineRound, SolverLog, StageLog

STORED = {
    "solver": "BoxFDDP",
    "iterations": 14,
    "cost": 12.5,
    "stop_criterion": 3e-8,
    "stop_threshold": 1e-7,
    "converged": True,
    "is_feasible": True,
    "solve_time_s": 0.4,
    "build_time_s": 0.2,
    "knots": 51,
    "ms_per_knot_iteration": 0.56,
    "solve_cpu_s": 0.5,
    "cpu_ms_per_knot_iteration": 0.7,
    "stop_reason": "gradient",
    "stages": [{"scale": {"com": 0.1}, "iterations": 4, "cost": 20.0}, {"scale": {}, "iterations": 10, "cost": 12.5}],
    "nthreads": 1,
    "cost_terms": ["com", "state_reg"],
    "mass_kg": 72.5,
    "actuator_limits": {
        "enforced": ["stroke", "velocity", "force"],
        "mechanisms": ["knee"],
        "form": "per-knot joint boxes",
        "refreshes": 3,
        "python_cpu_s": 0.01,
        "refine_rounds": [{"violations": 2, "bounds_tightened": 1, "iterations": 5}],
        "within_limits": True,
        "violations_left": 0,
        "peak_utilisation": {"velocity": {"knots": ["LLKnee_Act1", 0.8], "1khz": ["LLKnee_Act1", 0.81]}},
    },
    "warm_start": False,
    "limit_factors": {"LLKnee:velocity": 2.0},
}


def test_round_trip_keeps_every_key_and_its_order() -> None:
    log = SolverLog.from_dict(STORED)
    assert log.to_dict() == STORED
    assert list(log.to_dict()) == list(STORED)
    assert json.loads(json.dumps(log.to_dict())) == STORED
    assert log.stages[0] == StageLog({"com": 0.1}, 4, 20.0)
    assert log.actuator_limits.refine_rounds == [RefineRound(2, 1, 5)]


def test_a_plan_without_actuator_limits_writes_only_enforced() -> None:
    log = SolverLog(actuator_limits=ActuatorLimitLog())
    assert log.to_dict()["actuator_limits"] == {"enforced": []}
    assert "limit_factors" not in log.to_dict()


def test_an_older_or_partial_log_loads_with_defaults() -> None:
    log = SolverLog.from_dict({"converged": True, "iterations": 7})
    assert log.converged
    assert log.iterations == 7
    assert not log.warm_start
    assert log.actuator_limits.enforced == []
    assert math.isnan(log.solve_cpu_s)


def test_unknown_keys_are_kept() -> None:
    log = SolverLog.from_dict({**STORED, "written_later": 1})
    assert log.extra == {"written_later": 1}
    assert log.to_dict() == {**STORED, "written_later": 1}
