"""Reading and writing bags without ROS: rosbag2 (sqlite3, MCAP), ROS 1 and plain MCAP.

:class:`BagSource` opens

- a rosbag2 folder (``metadata.yaml`` + ``.db3`` or ``.mcap`` files), or one of its storage
  files (the folder is opened), read with rosbags' ``AnyReader``;
- a ROS 1 ``.bag`` file, or a folder of split ``.bag`` files, read with ``AnyReader`` (the
  ROS 1 message definitions in the bag are converted by rosbags; field names stay ROS 1's);
- a plain MCAP file without rosbag2 metadata (what ``ros2 bag record`` leaves when it is killed,
  or what other MCAP writers produce), read with ``mcap`` and decoded by ``mcap_ros2``; its
  messages are attribute-access objects like rosbags' dataclasses. A file whose summary is
  missing or damaged is scanned from the start: the messages before the damage are yielded,
  then :class:`~dispeval_ros.errors.InputError` says where it broke. A rosbag2 MCAP bag whose
  storage file rosbags refuses (truncated) is read the same way.

Types are registered from each bag's own message definitions. Message type names are reported
in the ROS 2 form ``pkg/msg/Type``. Every problem (missing path, corrupt storage, undecodable
message) is an ``InputError`` with a one-line message naming the bag; no rosbags, mcap or
sqlite exception escapes.

:class:`BagWriter` writes rosbag2 bags (version 8, readable by ROS 2 Humble and later) in
sqlite3 or MCAP storage, or a single plain MCAP file with ``ros2msg`` schemas; messages are
CDR-serialised by rosbags.
"""

from dispeval_ros.io.bags.common import BAG_FORMATS, WRITE_FORMATS, TopicInfo
from dispeval_ros.io.bags.source import BagSource, require_topic
from dispeval_ros.io.bags.writer import BagWriter

__all__ = ["BAG_FORMATS", "WRITE_FORMATS", "BagSource", "BagWriter", "TopicInfo", "require_topic"]
