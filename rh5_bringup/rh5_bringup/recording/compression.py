"""MCAP chunk compression: zstd (the default, as rosbag2's ``zstd_fast``/``zstd_small`` presets) or none.

The MCAP specification names the compression of a chunk in the chunk record (``""`` or ``"zstd"``,
also ``"lz4"``, which this recorder never writes). A compressed chunk keeps the size and CRC of its
uncompressed records, so a reader checks what it decompressed; zstd frames carry their content size.
"""

from __future__ import annotations

from typing import Final

import zstandard

__all__ = ["COMPRESSIONS", "DEFAULT_COMPRESSION", "DEFAULT_LEVEL", "ChunkCompressor", "decompress"]

COMPRESSIONS: Final = ("zstd", "")
"""What the writer can write: zstd, or uncompressed chunks."""
DEFAULT_COMPRESSION: Final = "zstd"
DEFAULT_LEVEL: Final = 1
"""zstd level 1: about 3x smaller JointState chunks at several hundred MB/s per core."""


class ChunkCompressor:
    """Compresses the records of one chunk after another with a reused zstd context (one thread)."""

    def __init__(self, compression: str = DEFAULT_COMPRESSION, level: int = DEFAULT_LEVEL) -> None:
        if compression not in COMPRESSIONS:
            msg = f"compression must be one of {list(COMPRESSIONS)}, got {compression!r}"
            raise ValueError(msg)
        self.compression = compression
        self.level = level
        self._zstd = zstandard.ZstdCompressor(level=level, write_content_size=True) if compression else None

    def compress(self, records: bytes | bytearray) -> bytes | bytearray:
        """The chunk's stored bytes: ``records`` compressed, or themselves when uncompressed."""
        if self._zstd is None:
            return records
        return self._zstd.compress(records)


def decompress(compression: str, stored: bytes | memoryview, size: int) -> bytes | memoryview:
    """The uncompressed records of a chunk; LookupError for an unknown compression, ValueError for bad data."""
    if compression == "":
        return stored
    if compression != "zstd":
        msg = f"chunk compression {compression!r} is not supported (only zstd or none)"
        raise LookupError(msg)
    try:
        records = zstandard.ZstdDecompressor().decompress(stored, max_output_size=size)
    except zstandard.ZstdError as err:
        msg = f"zstd chunk does not decompress: {err}"
        raise ValueError(msg) from err
    if len(records) != size:
        msg = f"zstd chunk decompressed to {len(records)} bytes, expected {size}"
        raise ValueError(msg)
    return records
