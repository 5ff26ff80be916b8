"""The sole's support rectangle: one number shared by the optimiser's CoP cost (ocp.costs) and the CoP checks of the
limit analysis and the plots."""

from __future__ import annotations

from typing import Final

FOOT_SIZE_M: Final = (0.200, 0.080)
"""Sole support rectangle length x width (rh5_paper_facts.yaml legs.foot.support_polygon_m)."""
