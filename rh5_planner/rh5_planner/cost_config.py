"""The planner's cost configuration (config/costs.yaml): loading it and merging a motion's overrides.

Apart from the problem so that the limit analysis can read the contact settings without importing Crocoddyl.
"""

from __future__ import annotations

import copy
import functools
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final

import yaml

COSTS_FILE: Final = Path(__file__).parent / "config" / "costs.yaml"


@functools.cache
def _cost_config_cached(path: str) -> dict[str, Any]:
    with open(path, encoding="utf-8") as file:
        return yaml.safe_load(file)  # type: ignore[no-any-return]


def load_cost_config(path: str | Path | None = None) -> dict[str, Any]:
    """The cost configuration (config/costs.yaml by default), as a fresh dict."""
    return copy.deepcopy(_cost_config_cached(str(path or COSTS_FILE)))


def motion_config(name: str, config: Mapping[str, Any]) -> dict[str, Any]:
    """``config`` with its ``motion_overrides[name]`` section merged in (per-term settings of one motion)."""
    merged = copy.deepcopy(dict(config))
    for term, settings in (config.get("motion_overrides") or {}).get(name, {}).items():
        merged[term] = {**merged.get(term, {}), **settings} if isinstance(settings, Mapping) else settings
    return merged
