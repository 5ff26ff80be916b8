"""Recording: rosbag2-compatible MCAP bags written without rosbag2 (no ROS imports at module level).

* :class:`BagWriter` writes ``<bag>/metadata.yaml`` + ``<bag>/<bag>_0.mcap`` as ``ros2 bag record -s mcap``
  does (rosbag2 Jazzy, metadata version 9), readable up to its last chunk if the process is killed;
* :class:`QueuedBagWriter` runs one in a thread fed by a non-blocking queue (the recorder node);
* :func:`recover_bag` completes a killed recorder's bag (summary, footer, metadata.yaml);
* :func:`read_bag_info` describes a bag from its MCAP files (``rh5 bag info``);
* ``mcap_format`` holds the MCAP record encoders the writers share, ``compression`` the chunks' zstd.
"""

from rh5_bringup.recording.bag import (
    DEFAULT_CHUNK_MAX_AGE_S,
    BagWriter,
    bag_files,
    mcap_file_of,
    type_description_hash,
)
from rh5_bringup.recording.compression import COMPRESSIONS, DEFAULT_COMPRESSION
from rh5_bringup.recording.errors import BagRecoveryError, BagWriterError, RecordingError
from rh5_bringup.recording.info import BagInfo, format_bag_info, read_bag_info
from rh5_bringup.recording.mcap_writer import DEFAULT_CHUNK_SIZE, McapStreamWriter
from rh5_bringup.recording.metadata import BagTopic, OfferedQos
from rh5_bringup.recording.queued_writer import DEFAULT_MAX_PENDING, QueuedBagWriter
from rh5_bringup.recording.recovery import RecoveryResult, is_complete, recover_bag

__all__ = [
    "COMPRESSIONS",
    "DEFAULT_CHUNK_MAX_AGE_S",
    "DEFAULT_CHUNK_SIZE",
    "DEFAULT_COMPRESSION",
    "DEFAULT_MAX_PENDING",
    "BagInfo",
    "BagRecoveryError",
    "BagTopic",
    "BagWriter",
    "BagWriterError",
    "McapStreamWriter",
    "OfferedQos",
    "QueuedBagWriter",
    "RecordingError",
    "RecoveryResult",
    "bag_files",
    "format_bag_info",
    "is_complete",
    "mcap_file_of",
    "read_bag_info",
    "recover_bag",
    "type_description_hash",
]
