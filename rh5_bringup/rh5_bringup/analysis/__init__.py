"""Experiment reports from recorded bags: PNG plots and a Markdown summary (``rh5 report BAG``).

``write_report(bag)`` reads a rosbag2 folder written by the suite's recorder and writes, into
``<bag folder's parent>/<bag name>_report/`` by default (next to the bag, never inside it, so the
recording stays as recorded), ``report.md`` with verdict lines and tables, and the figures:
``tracking.png`` (the paper's left-ankle tracking figure), ``base_deviation.png`` (floating base vs
plan with the paper's PyBullet bands), ``tracking_errors.png`` (per joint) and, for requested
joints, ``extra_tracking.png``. Running it again on the same bag regenerates the same files.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from rh5_bringup.analysis.load import load_recording
from rh5_bringup.analysis.records import NotABagError, Recording, ReportError
from rh5_bringup.analysis.results import Analysis, analyse, check_names

__all__ = [
    "REPORT_FILE",
    "Analysis",
    "NotABagError",
    "Recording",
    "Report",
    "ReportError",
    "analyse",
    "build_report",
    "default_out_dir",
    "load_recording",
    "write_report",
]

REPORT_FILE: Final = "report.md"
FIGURE_FILES: Final = {
    "tracking": "tracking.png",
    "base": "base_deviation.png",
    "errors": "tracking_errors.png",
    "extra": "extra_tracking.png",
}


@dataclass(frozen=True)
class Report:
    """What was written: the folder, the Markdown file, the figures (key -> path) and the verdict lines."""

    folder: Path
    markdown: Path
    figures: dict[str, Path]
    verdicts: list[str]
    analysis: Analysis


def default_out_dir(bag: Path) -> Path:
    """``<parent>/<bag name>_report``: beside the bag folder, so the recording itself is never modified."""
    bag = Path(bag).resolve()
    return bag.parent / f"{bag.name}_report"


def build_report(bag: Path, out_dir: Path | None = None, joints: Sequence[str] = ()) -> Report:
    """Read ``bag``, compute every section, write the figures and ``report.md``; ReportError if impossible."""
    from rh5_bringup.analysis import figures, markdown  # noqa: PLC0415  (matplotlib only when a report is made)

    extra = check_names(joints)
    recording = load_recording(Path(bag))
    analysis = analyse(recording, extra)
    folder = Path(out_dir) if out_dir is not None else default_out_dir(bag)
    folder.mkdir(parents=True, exist_ok=True)
    drawn: dict[str, Path | None] = {
        "tracking": figures.paper_tracking_figure(analysis, folder / FIGURE_FILES["tracking"]),
        "base": figures.base_figure(analysis, folder / FIGURE_FILES["base"]),
        "errors": figures.error_bars_figure(analysis, folder / FIGURE_FILES["errors"]),
        "extra": figures.tracking_figure(analysis, folder / FIGURE_FILES["extra"], extra, columns=1) if extra else None,
    }
    for key, path in drawn.items():  # a figure that cannot be drawn this time must not linger from an earlier run
        if path is None:
            (folder / FIGURE_FILES[key]).unlink(missing_ok=True)
    written = {k: p for k, p in drawn.items() if p is not None}
    text = markdown.render(analysis, {k: p.name for k, p in written.items()})
    target = folder / REPORT_FILE
    target.write_text(text, encoding="utf-8")
    return Report(folder, target, written, markdown.verdict_lines(analysis), analysis)


def write_report(bag: Path, out_dir: Path | None = None, joints: Sequence[str] = ()) -> Path:
    """Write the report of ``bag`` (PNG plots + report.md) and return the report folder.

    ``out_dir`` defaults to ``default_out_dir(bag)``; ``joints`` adds tracking plots and rows for any
    joints or actuators. Raises NotABagError for a path that is not a readable rosbag2 folder and
    ReportError for unknown joint names.
    """
    return build_report(bag, out_dir, joints).folder
