"""The solver log of a plan as typed records: what Box-FDDP did, how long it took, which limits it enforced.

``PlanResult.solver_log`` is a :class:`SolverLog`; trajectory files, the solver child's result line and sweep
checkpoints keep it as the JSON object ``to_dict()`` writes, with the same keys as always. ``from_dict`` reads
those, also ones written before a key existed (the key's default then) or after (kept in ``extra``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = ["ActuatorLimitLog", "RefineRound", "SolverLog", "StageLog"]


def _known(cls: type, data: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """``data`` split into the fields of dataclass ``cls`` and the rest."""
    names = {f.name for f in dataclasses.fields(cls)}
    return {k: v for k, v in data.items() if k in names}, {k: v for k, v in data.items() if k not in names}


@dataclass(frozen=True)
class StageLog:
    """One continuation stage: the cost scales it ran with, its iterations and its final cost."""

    scale: dict[str, float] = field(default_factory=dict)
    iterations: int = 0
    cost: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of the stage."""
        return {"scale": dict(self.scale), "iterations": self.iterations, "cost": self.cost}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> StageLog:
        """The stage from its JSON object."""
        known, _ = _known(cls, data)
        return cls(**known)


@dataclass(frozen=True)
class RefineRound:
    """One round of the actuator-limit refinement: violations found, bounds tightened, iterations spent."""

    violations: int = 0
    bounds_tightened: int = 0
    iterations: int = 0

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of the round."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RefineRound:
        """The round from its JSON object."""
        known, _ = _known(cls, data)
        return cls(**known)


@dataclass(frozen=True)
class ActuatorLimitLog:
    """The actuator limits in the plan (costs.yaml ``actuator_limits``). A plan without them has only an empty
    ``enforced``; the other fields are then None and left out of the JSON object."""

    enforced: list[str] = field(default_factory=list)
    """Limit kinds enforced (stroke, velocity, force); empty: planned without actuator limits."""
    mechanisms: list[str] | None = None
    form: str | None = None
    refreshes: int | None = None
    python_cpu_s: float | None = None
    refine_rounds: list[RefineRound] | None = None
    within_limits: bool | None = None
    violations_left: int | None = None
    peak_utilisation: dict[str, Any] | None = None
    """kind -> {knots: [actuator, use], 1khz: [actuator, use]} (``ActuatorCheck.summary``)."""

    def to_dict(self) -> dict[str, Any]:
        """The JSON object, fields that are None left out."""
        out: dict[str, Any] = {"enforced": list(self.enforced)}
        for f in dataclasses.fields(self)[1:]:
            value = getattr(self, f.name)
            if value is not None:
                out[f.name] = [r.to_dict() for r in value] if f.name == "refine_rounds" else value
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None) -> ActuatorLimitLog:
        """The record from its JSON object (None or empty: no actuator limits)."""
        known, _ = _known(cls, data or {})
        if known.get("refine_rounds") is not None:
            known["refine_rounds"] = [RefineRound.from_dict(r) for r in known["refine_rounds"]]
        return cls(**known)


@dataclass(frozen=True)
class SolverLog:
    """What one solve did (:func:`rh5_planner.ocp.solve`), field for field the keys of the stored log."""

    solver: str = "BoxFDDP"
    iterations: int = 0
    """Box-FDDP iterations over all continuation stages and refinement rounds."""
    cost: float = math.nan
    stop_criterion: float = math.nan
    stop_threshold: float = math.nan
    converged: bool = False
    is_feasible: bool = False
    solve_time_s: float = math.nan
    build_time_s: float = math.nan
    knots: int = 0
    ms_per_knot_iteration: float = math.nan
    solve_cpu_s: float = math.nan
    """CPU time of the solving process (all its threads): robust where other processes share the cores."""
    cpu_ms_per_knot_iteration: float = math.nan
    stop_reason: str = ""
    """gradient, cost_stalled or iteration_limit."""
    stages: list[StageLog] = field(default_factory=list)
    nthreads: int = 1
    cost_terms: list[str] = field(default_factory=list)
    mass_kg: float = math.nan
    actuator_limits: ActuatorLimitLog = field(default_factory=ActuatorLimitLog)
    warm_start: bool = False
    """Whether the solve started from another solution (``solve(guess=...)``)."""
    limit_factors: dict[str, float] | None = None
    """``joint:kind`` -> factor for the scaled limits that differ from 1 (None: none scaled; left out of the JSON)."""
    extra: dict[str, Any] = field(default_factory=dict)
    """Keys of a stored log this record does not know, kept so that it is written back unchanged."""

    def to_dict(self) -> dict[str, Any]:
        """The JSON object, with the keys of the stored log in their order."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name == "stages":
                value = [s.to_dict() for s in value]
            elif f.name == "actuator_limits":
                value = value.to_dict()
            elif f.name in ("limit_factors", "extra"):
                continue
            elif isinstance(value, list):
                value = list(value)
            out[f.name] = value
        if self.limit_factors is not None:
            out["limit_factors"] = dict(self.limit_factors)
        out.update(self.extra)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> SolverLog:
        """The record from a stored log; missing keys take their defaults, unknown ones go to ``extra``."""
        known, extra = _known(cls, data)
        known.pop("extra", None)
        if "stages" in known:
            known["stages"] = [StageLog.from_dict(s) for s in known["stages"]]
        if "actuator_limits" in known:
            known["actuator_limits"] = ActuatorLimitLog.from_dict(known["actuator_limits"])
        return cls(**known, extra=extra)
