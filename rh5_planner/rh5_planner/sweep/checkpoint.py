"""The checkpoint of a sweep: every finished point is on disk the moment its result arrives.

One folder per sweep:

* ``sweep.json``: what the sweep is (motion, axes, ``--set``, solver settings); a resume must be the same sweep;
* ``points.jsonl``: one JSON row per finished point, appended and flushed to disk as each result arrives;
* ``warm/<point>.npz``: the solution of each converged point, written before its row, so that a resumed sweep
  warm-starts the remaining points exactly as an uninterrupted one would.

A sweep killed at any moment leaves at worst a half-written last line, which the next load ignores. Resuming keeps
every row except ``failed`` ones (an error, or a task whose workers all died), which are solved again.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final

import numpy as np

from .point import PointOutcome, WarmStart

__all__ = ["Checkpoint", "CheckpointMismatchError"]

DESCRIPTION: Final = "sweep.json"
ROWS: Final = "points.jsonl"
WARM: Final = "warm"


class CheckpointMismatchError(ValueError):
    """The folder holds the checkpoint of another sweep."""


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    msg = f"not JSON-able: {type(value).__name__}"
    raise TypeError(msg)


class Checkpoint:
    """The checkpoint folder of one sweep (see the module docstring)."""

    def __init__(self, folder: str | Path, description: Mapping[str, Any], *, restart: bool = False) -> None:
        """Open ``folder`` for the sweep ``description``; CheckpointMismatchError if it holds another sweep's checkpoint
        (``restart`` discards it instead)."""
        self.folder = Path(folder)
        self.description = json.loads(json.dumps(dict(description), default=_json_default))
        self.folder.mkdir(parents=True, exist_ok=True)
        (self.folder / WARM).mkdir(exist_ok=True)
        described = self.folder / DESCRIPTION
        if described.exists() and not restart:
            stored = json.loads(described.read_text(encoding="utf-8"))
            if stored != self.description:
                msg = (
                    f"{self.folder} holds the checkpoint of another sweep ({_difference(stored, self.description)}); "
                    "choose another --output-dir or pass --restart to discard it"
                )
                raise CheckpointMismatchError(msg)
        elif restart:
            (self.folder / ROWS).unlink(missing_ok=True)
            for old in (self.folder / WARM).glob("*.npz"):
                old.unlink()
        described.write_text(json.dumps(self.description, indent=1) + "\n", encoding="utf-8")
        self.rows: dict[str, dict[str, Any]] = self._load()

    def _load(self) -> dict[str, dict[str, Any]]:
        path = self.folder / ROWS
        rows: dict[str, dict[str, Any]] = {}
        if not path.exists():
            return rows
        for line in path.read_text(encoding="utf-8").splitlines():
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                continue  # the half-written last line of a killed sweep
            if isinstance(row, dict) and "point" in row:
                rows[str(row["point"])] = row
        return rows

    def done(self) -> dict[str, dict[str, Any]]:
        """Rows that a resume keeps (every status but ``failed``), by point id."""
        return {p: r for p, r in self.rows.items() if r.get("status") != "failed"}

    def record(self, outcome: PointOutcome) -> None:
        """Store one result: its solution (if any), then its row, flushed to disk."""
        point = str(outcome.row["point"])
        if outcome.warm is not None:
            target = self.folder / WARM / f"{point}.npz"
            partial = target.with_suffix(".partial.npz")
            np.savez(partial, **outcome.warm.to_arrays())
            os.replace(partial, target)
        line = json.dumps(outcome.row, default=_json_default, allow_nan=True)
        with (self.folder / ROWS).open("a", encoding="utf-8") as file:
            file.write(line + "\n")
            file.flush()
            os.fsync(file.fileno())
        self.rows[point] = outcome.row

    def warm_start(self, point: str) -> WarmStart | None:
        """The stored solution of ``point`` (None: it has none, e.g. it did not converge)."""
        path = self.folder / WARM / f"{point}.npz"
        if not path.exists():
            return None
        with np.load(path) as arrays:
            return WarmStart.from_arrays({k: arrays[k] for k in arrays.files})


def _difference(stored: Mapping[str, Any], wanted: Mapping[str, Any]) -> str:
    keys = sorted(k for k in {*stored, *wanted} if stored.get(k) != wanted.get(k))
    return "differs in " + ", ".join(keys)
