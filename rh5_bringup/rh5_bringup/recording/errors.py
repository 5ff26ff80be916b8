"""The recording's errors, by phase: writing a bag, recovering one."""

from __future__ import annotations

__all__ = ["BagRecoveryError", "BagWriterError", "RecordingError"]


class RecordingError(RuntimeError):
    """Base of the recording errors."""


class BagWriterError(RecordingError):
    """A bag cannot be created or written (exists already, wrong lifecycle step, unknown topic, I/O)."""


class BagRecoveryError(RecordingError):
    """A bag cannot be recovered (no MCAP header, a chunk compression other than zstd or none)."""
