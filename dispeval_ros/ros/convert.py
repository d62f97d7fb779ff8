"""Score records and arrays as ROS messages (rclpy message classes), and back.

- :class:`~dispeval_ros.stream.vectors.StatusRecord` ↔ ``diagnostic_msgs/DiagnosticStatus``
  (``level`` is a ROS ``byte``: a length-1 ``bytes`` in rclpy, not an int).
- A score vector → ``std_msgs/Float64MultiArray`` with one dimension labelled
  :data:`VECTOR_DIM_LABEL` whose size is the vector length. The label of each element
  (``criterion/measure`` in :func:`~dispeval_ros.stream.vectors.vector_labels` order) is published
  once, latched, as a JSON list in a ``std_msgs/String`` on ``/dispeval/NAME/vector_labels``.
- numpy → ``sensor_msgs/Image`` (32FC1, rgb8 or any encoding of
  :data:`~dispeval_ros.io.messages.IMAGE_ENCODINGS`), little-endian and unpadded.

Buffers are handed to rclpy as ``array.array``: the generated setters take those without a
per-element check (a list or numpy array would be checked value by value).
"""

from __future__ import annotations

import array
import json
from collections.abc import Sequence
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from sensor_msgs.msg import Image
from std_msgs.msg import Float64MultiArray, Header, MultiArrayDimension, MultiArrayLayout, String

from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.messages import IMAGE_ENCODINGS
from dispeval_ros.stream.vectors import StatusRecord

VECTOR_DIM_LABEL = "criterion/measure"
"""Label of the single dimension of every score vector (its elements are criterion/measure)."""

_NS = 1_000_000_000


def time_msg(stamp_ns: int) -> Time:
    """``builtin_interfaces/Time`` of a stamp in nanoseconds."""
    sec, nanosec = divmod(int(stamp_ns), _NS)
    return Time(sec=sec, nanosec=nanosec)


def header_msg(stamp_ns: int, frame_id: str = "") -> Header:
    """``std_msgs/Header`` of a stamp in nanoseconds."""
    return Header(stamp=time_msg(stamp_ns), frame_id=str(frame_id))


def status_msg(record: StatusRecord) -> DiagnosticStatus:
    """One ``diagnostic_msgs/DiagnosticStatus`` (values in the record's order)."""
    return DiagnosticStatus(
        level=bytes([record.level]),
        name=record.name,
        message=record.message,
        hardware_id=record.hardware_id,
        values=[KeyValue(key=key, value=value) for key, value in record.values],
    )


def diagnostic_array(
    stamp_ns: int, records: Sequence[StatusRecord], frame_id: str = ""
) -> DiagnosticArray:
    """A ``diagnostic_msgs/DiagnosticArray`` stamped ``stamp_ns`` holding ``records``."""
    return DiagnosticArray(
        header=header_msg(stamp_ns, frame_id), status=[status_msg(r) for r in records]
    )


def status_level(status: Any) -> int:
    """The level of a DiagnosticStatus as an int (rclpy gives ``bytes`` of length 1)."""
    level = status.level
    if isinstance(level, (bytes, bytearray)):
        return level[0] if level else 0
    return int(level)


def status_values(status: Any) -> list[tuple[str, str]]:
    """The ``(key, value)`` pairs of a DiagnosticStatus, in order."""
    return [(str(item.key), str(item.value)) for item in status.values]


def status_record(status: Any) -> StatusRecord:
    """A received ``DiagnosticStatus`` as the transport-free record it was made from."""
    return StatusRecord(
        str(status.name),
        str(status.hardware_id),
        status_level(status),
        str(status.message),
        tuple(status_values(status)),
    )


def vector_msg(values: Sequence[float]) -> Float64MultiArray:
    """A score vector: ``layout.dim[0]`` is (:data:`VECTOR_DIM_LABEL`, n, n), offset 0."""
    size = len(values)
    layout = MultiArrayLayout(
        dim=[MultiArrayDimension(label=VECTOR_DIM_LABEL, size=size, stride=size)],
        data_offset=0,
    )
    return Float64MultiArray(layout=layout, data=array.array("d", (float(v) for v in values)))


def labels_msg(labels: Sequence[str]) -> String:
    """The element labels of a score vector, as a JSON list of strings."""
    return String(data=json.dumps(list(labels)))


def image_msg(pixels: np.ndarray, stamp_ns: int, frame_id: str, encoding: str) -> Image:
    """A little-endian, unpadded ``sensor_msgs/Image`` of an H×W (or H×W×C) array."""
    try:
        dtype, channels = IMAGE_ENCODINGS[encoding]
    except KeyError:
        raise ConfigurationError(
            f"image encoding '{encoding}' is not supported; expected one of "
            + ", ".join(IMAGE_ENCODINGS)
        ) from None
    data = np.ascontiguousarray(pixels, dtype=np.dtype(dtype).newbyteorder("<"))
    if channels == 1 and data.ndim == 3 and data.shape[2] == 1:
        data = data[:, :, 0]
    expected = 2 if channels == 1 else 3
    if data.ndim != expected or data.size == 0 or (channels > 1 and data.shape[2] != channels):
        raise ConfigurationError(
            f"{encoding} needs a non-empty {'H×W' if channels == 1 else f'H×W×{channels}'} "
            f"array, got shape {data.shape}"
        )
    height, width = int(data.shape[0]), int(data.shape[1])
    return Image(
        header=header_msg(stamp_ns, frame_id),
        height=height,
        width=width,
        encoding=encoding,
        is_bigendian=0,
        step=width * channels * data.itemsize,
        data=array.array("B", data.tobytes()),
    )
