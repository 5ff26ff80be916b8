"""Recording: rosbag2-compatible MCAP bags written without rosbag2 (no ROS imports at module level).

* :class:`BagWriter` writes ``<bag>/metadata.yaml`` + ``<bag>/<bag>_0.mcap`` as ``ros2 bag record -s mcap``
  does (rosbag2 Jazzy, metadata version 9), readable up to its last chunk if the process is killed;
* :class:`QueuedBagWriter` runs one in a thread fed by a non-blocking queue (the recorder node);
* :func:`recover_bag` completes a killed recorder's bag (summary, footer, metadata.yaml);
* ``mcap_format`` holds the MCAP record encoders the writers share.
"""

from rh5_bringup.recording.bag import DEFAULT_CHUNK_MAX_AGE_S, BagWriter, mcap_file_of, type_description_hash
from rh5_bringup.recording.errors import BagRecoveryError, BagWriterError, RecordingError
from rh5_bringup.recording.mcap_writer import DEFAULT_CHUNK_SIZE, McapStreamWriter
from rh5_bringup.recording.metadata import BagTopic, OfferedQos
from rh5_bringup.recording.queued_writer import DEFAULT_MAX_PENDING, QueuedBagWriter
from rh5_bringup.recording.recovery import RecoveryResult, is_complete, recover_bag

__all__ = [
    "DEFAULT_CHUNK_MAX_AGE_S",
    "DEFAULT_CHUNK_SIZE",
    "DEFAULT_MAX_PENDING",
    "BagRecoveryError",
    "BagTopic",
    "BagWriter",
    "BagWriterError",
    "McapStreamWriter",
    "OfferedQos",
    "QueuedBagWriter",
    "RecordingError",
    "RecoveryResult",
    "is_complete",
    "mcap_file_of",
    "recover_bag",
    "type_description_hash",
]
