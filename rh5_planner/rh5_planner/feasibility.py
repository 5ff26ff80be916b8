"""The paper's feasibility table ("Capabilities of the RH5 humanoid to perform a wide range of motions respecting the
hardware limits", tab:systemLimits): limit analyses as rows, printed as text or Markdown and compared with the paper.

:class:`FeasibilityTable` puts analyses (:class:`rh5_planner.limit_analysis.LimitAnalysis`) in the paper's form: a
tick where every limit holds, else the number of joints, or actuators, violating it; for CoP and friction the number
of foot-knots outside. :data:`PAPER_FEASIBILITY` holds the paper's own entries.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final, Protocol

from .limit_scale import ACTUATOR_KINDS, LimitScale

__all__ = ["COLUMNS", "COLUMN_TITLES", "PAPER_FEASIBILITY", "AnalysedMotion", "Comparison", "FeasibilityTable"]

COLUMNS: Final = ("position", "torque", "velocity", *ACTUATOR_KINDS, "cop", "friction")
"""Columns of the feasibility table: the paper's three (its order: position, torque, velocity), ours after."""
COLUMN_TITLES: Final = {
    "position": "Pos. Lim.",
    "torque": "Torque Lim.",
    "velocity": "Vel. Lim.",
    "stroke": "Act. stroke",
    "actuator_velocity": "Act. vel.",
    "force": "Act. force",
    "cop": "CoP",
    "friction": "Friction",
}

PAPER_FEASIBILITY: Final[dict[str, dict[str, int]]] = {
    "walk_with_5kg_weights": {"position": 0, "torque": 0, "velocity": 0},
    "fast_walk_1m_s": {"position": 0, "torque": 0, "velocity": 0},
    "squat_with_5kg_weights": {"position": 0, "torque": 0, "velocity": 0},
    "vertical_jump_1cm": {"position": 0, "torque": 0, "velocity": 0},
    "vertical_jump_10cm": {"position": 0, "torque": 0, "velocity": 3},
    "obstacle_jumps": {"position": 0, "torque": 5, "velocity": 7},
}
"""The paper's table tab:systemLimits (Esser et al., RH5 paper; rh5_paper_facts.yaml ``feasibility``): 0 is a tick,
n > 0 the number of violations it reports. The text says the 10 cm jump exceeds the body pitch and knee velocity
limits (3 = BodyPitch and both knees): the counts are joints."""
_TICK: Final = "\u2713"
_CROSS: Final = "\u2717"


class AnalysedMotion(Protocol):
    """What a table row reads of a limit analysis (:class:`rh5_planner.limit_analysis.LimitAnalysis`). A protocol,
    so that this module does not import the analysis that prints its own row with it."""

    @property
    def motion(self) -> str:
        """The motion's name."""
        ...

    @property
    def converged(self) -> bool | None:
        """Whether the solve converged (None: unknown)."""
        ...

    @property
    def scale(self) -> LimitScale:
        """The limits the plan was checked against."""
        ...

    @property
    def actuator_limited(self) -> bool:
        """Whether the plan was made with the actuator limits in the problem."""
        ...

    def count(self, column: str) -> int | None:
        """The table entry of ``column``: 0 = holds; None = not available."""
        ...


@dataclass(frozen=True)
class Comparison:
    """One cell of the paper's table against ours."""

    motion: str
    column: str
    paper: int
    ours: int | None

    @property
    def agree(self) -> bool:
        """Same entry (tick and tick, or the same number of violating joints)."""
        return self.ours == self.paper

    @property
    def same_verdict(self) -> bool:
        """Both feasible or both infeasible for this limit (counts may differ)."""
        return self.ours is not None and (self.ours == 0) == (self.paper == 0)

    def describe(self) -> str:
        """``vertical_jump_10cm / Vel. Lim.: paper ✗3, ours ✗2: disagree (both violate)``."""
        if self.agree:
            verdict = "agree"
        elif self.same_verdict:
            verdict = "disagree (both violate, other count)"
        else:
            verdict = "DISAGREE"
        return (
            f"{self.motion} / {COLUMN_TITLES[self.column]}: paper {_entry(self.paper)}, ours {_entry(self.ours)}: "
            f"{verdict}"
        )


def _entry(count: int | None) -> str:
    if count is None:
        return "n/a"
    return _TICK if count == 0 else f"{_CROSS}{count}"


@dataclass(frozen=True, eq=False)
class FeasibilityTable:
    """Analyses of several motions in the paper's table form (rows: motions, columns: :data:`COLUMNS`)."""

    analyses: Sequence[AnalysedMotion]
    columns: tuple[str, ...] = COLUMNS

    def rows(self) -> list[tuple[str, list[str]]]:
        """(motion, cells) with ticks, crosses and counts."""
        return [(a.motion, [_entry(a.count(c)) for c in self.columns]) for a in self.analyses]

    def _header(self) -> list[str]:
        return ["Motion", "Conv.", *(COLUMN_TITLES[c] for c in self.columns)]

    def _body(self) -> list[list[str]]:
        out = []
        for a, (motion, cells) in zip(self.analyses, self.rows(), strict=True):
            conv = {True: "yes", False: "NO", None: "?"}[a.converged]
            label = motion + (" +act" if a.actuator_limited else "") + (f" [{a.scale.describe()}]" if a.scale else "")
            out.append([label, conv, *cells])
        return out

    def to_markdown(self) -> str:
        """GitHub Markdown table."""
        header = self._header()
        lines = ["| " + " | ".join(header) + " |", "|" + "|".join(["---", *[":-:"] * (len(header) - 1)]) + "|"]
        lines += ["| " + " | ".join(row) + " |" for row in self._body()]
        return "\n".join(lines) + "\n\n" + _LEGEND

    def to_text(self) -> str:
        """Plain text with aligned columns."""
        rows = [self._header(), *self._body()]
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        lines = [
            "  ".join(
                cell.ljust(w) if i == 0 else cell.center(w) for i, (cell, w) in enumerate(zip(row, widths, strict=True))
            ).rstrip()
            for row in rows
        ]
        lines.insert(1, "-" * len(lines[0]))
        return "\n".join(lines) + "\n" + _LEGEND

    def compare_with_paper(self) -> list[Comparison]:
        """Every cell the paper has (motions of :data:`PAPER_FEASIBILITY` present here, its three columns)."""
        out = []
        for a in self.analyses:
            paper = PAPER_FEASIBILITY.get(a.motion)
            if paper is None:
                continue
            out.extend(Comparison(a.motion, c, paper[c], a.count(c)) for c in ("position", "torque", "velocity"))
        return out

    def comparison_text(self) -> str:
        """The paper's table next to ours, one line per cell, and the agreement count."""
        comparisons = self.compare_with_paper()
        if not comparisons:
            return "No motion of the paper's table (tab:systemLimits) in this table.\n"
        agree = sum(c.agree for c in comparisons)
        verdict = sum(c.same_verdict for c in comparisons)
        lines = ["Comparison with the paper's table (tab:systemLimits):"]
        lines += [f"  {c.describe()}" for c in comparisons]
        lines.append(f"{agree}/{len(comparisons)} cells agree; {verdict}/{len(comparisons)} give the same verdict.")
        return "\n".join(lines) + "\n"


_LEGEND: Final = (
    f"{_TICK}: the limit holds at every knot; {_CROSS}n: n joints (Pos./Torque/Vel., joint space) or n actuators "
    "(Act. *, parallel mechanisms and head) exceed it; CoP/Friction: foot-knots in contact outside the allowed "
    "region; n/a: mapping to actuator space failed; +act: planned with the actuator limits in the problem.\n"
)
