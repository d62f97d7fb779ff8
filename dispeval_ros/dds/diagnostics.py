"""Transport-free records ↔ the ROS 2 messages the DDS front ends publish (rosbags objects).

- :class:`~dispeval_ros.stream.vectors.StatusRecord` lists ↔ ``diagnostic_msgs/msg/DiagnosticArray``
  (``header.stamp`` = the frame's ground-truth stamp, one ``DiagnosticStatus`` per record,
  ``values`` as ``KeyValue`` pairs);
- score vectors → ``std_msgs/msg/Float64MultiArray`` with one dimension whose label is the
  comma-separated list of the element labels (``all/n,all/density,all/bmp,…``), so a consumer
  knows what each number is without another topic.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from dispeval_ros.dds.wire import DIAGNOSTIC_ARRAY, FLOAT64_MULTI_ARRAY
from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.stream.vectors import StatusRecord

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

_NS = 1_000_000_000


def header(typestore: Typestore, stamp: int, frame_id: str = "") -> Any:
    """A ``std_msgs/msg/Header`` with the stamp in nanoseconds."""
    sec, nanosec = divmod(int(stamp), _NS)
    time = typestore.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
    return typestore.types["std_msgs/msg/Header"](stamp=time, frame_id=frame_id)


def diagnostic_array(
    typestore: Typestore, stamp: int, records: Sequence[StatusRecord], frame_id: str = ""
) -> Any:
    """One ``DiagnosticArray`` holding a ``DiagnosticStatus`` per record."""
    key_value = typestore.types["diagnostic_msgs/msg/KeyValue"]
    status = typestore.types["diagnostic_msgs/msg/DiagnosticStatus"]
    return typestore.types[DIAGNOSTIC_ARRAY](
        header=header(typestore, stamp, frame_id),
        status=[
            status(
                level=int(record.level),
                name=record.name,
                message=record.message,
                hardware_id=record.hardware_id,
                values=[key_value(key=key, value=value) for key, value in record.values],
            )
            for record in records
        ],
    )


def records_of(msg: Any) -> tuple[int, list[StatusRecord]]:
    """A ``DiagnosticArray`` back into (header stamp, records)."""
    records = [
        StatusRecord(
            name=str(status.name),
            hardware_id=str(status.hardware_id),
            level=int(status.level),
            message=str(status.message),
            values=tuple((str(kv.key), str(kv.value)) for kv in status.values),
        )
        for status in msg.status
    ]
    return stamp_ns(msg.header), records


def vector_message(typestore: Typestore, labels: Sequence[str], values: Sequence[float]) -> Any:
    """A ``Float64MultiArray``: one dimension labelled with the element labels, then the data."""
    dimension = typestore.types["std_msgs/msg/MultiArrayDimension"](
        label=",".join(labels), size=len(values), stride=len(values)
    )
    layout = typestore.types["std_msgs/msg/MultiArrayLayout"](dim=[dimension], data_offset=0)
    return typestore.types[FLOAT64_MULTI_ARRAY](
        layout=layout, data=np.asarray(values, dtype=np.float64)
    )


def vector_labels_of(msg: Any) -> list[str]:
    """The element labels of a vector published by :func:`vector_message`."""
    if not msg.layout.dim:
        return []
    return [label for label in str(msg.layout.dim[0].label).split(",") if label]
