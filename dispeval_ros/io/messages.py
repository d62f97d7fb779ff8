"""Conversion between ROS messages and numpy, without ROS.

The decode functions are duck-typed: they read attributes, so they accept the message
dataclasses of rosbags' typestores (ROS 2 field names such as ``t``, ``p``, ``k`` and the ROS 1
ones ``T``, ``P``, ``K``), the dynamic objects of ``mcap_ros2`` and rclpy's messages alike.
Pixel buffers may be ``bytes``, ``bytearray``, ``memoryview``, ``array.array`` or a numpy
``uint8`` array; they are converted with numpy views (no per-pixel Python loop), honouring
``step`` (row padding) and ``is_bigendian``. Every array returned is a fresh, C-contiguous,
native-endian copy, so it never aliases a message buffer.

The encoders (numpy → messages, to write bags) are in :mod:`dispeval_ros.io.encoders`.

Every problem with a message raises a :mod:`dispeval_ros.errors` exception whose one-line
message names the topic, what was expected and what came.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.transforms import StaticTransform, check_rotation, matrix_from_pose
from dispeval_ros.errors import CalibrationError, ConfigurationError, InputError

__all__ = [
    "GT_ENCODINGS",
    "IMAGE_ENCODINGS",
    "CloudFrame",
    "DisparityFrame",
    "ImageFrame",
    "camera_from_info_and_baseline",
    "camera_from_infos",
    "cloud_from_msg",
    "disparity_from_msg",
    "gt_disparity",
    "image_from_msg",
    "rectified_camera_from_info",
    "stamp_ns",
    "static_transforms_from_msg",
]

_NS = 1_000_000_000

#: ``sensor_msgs/Image`` encodings :func:`image_from_msg` decodes → (dtype, channels).
IMAGE_ENCODINGS: Mapping[str, tuple[type[np.generic], int]] = {
    "32FC1": (np.float32, 1),
    "64FC1": (np.float64, 1),
    "16UC1": (np.uint16, 1),
    "mono16": (np.uint16, 1),
    "8UC1": (np.uint8, 1),
    "mono8": (np.uint8, 1),
    "rgb8": (np.uint8, 3),
    "bgr8": (np.uint8, 3),
}
_CANONICAL = {name.lower(): name for name in IMAGE_ENCODINGS}

#: Encodings :func:`gt_disparity` accepts for ground truth (disparity or depth).
GT_ENCODINGS = ("32FC1", "64FC1", "16UC1", "mono16")
_GT_KINDS = ("disparity", "depth")
#: Default scale of 16-bit ground truth: KITTI disparity (value / 256) and depth in millimetres.
_INT_SCALE = {"disparity": 256.0, "depth": 1000.0}
#: Camera units whose baseline can be converted to metres for depth ground truth.
_METRES_PER_UNIT = {"m": 1.0, "cm": 0.01, "mm": 0.001}


# -- small helpers --------------------------------------------------------------------------


def _where(topic: str, what: str) -> str:
    """``'DisparityImage on /topic'`` or ``'DisparityImage message'`` for error messages."""
    return f"{what} on {topic}" if topic else f"{what} message"


def _field(msg: Any, names: tuple[str, ...], where: str) -> Any:
    """The first of ``names`` the message has (ROS 2 and ROS 1 spellings)."""
    for name in names:
        value = getattr(msg, name, None)
        if value is not None:
            return value
    raise InputError(
        f"{where}: message of type {type(msg).__name__} has no field '{names[0]}'"
        " (is it the right message type?)"
    )


def _int(msg: Any, name: str, where: str) -> int:
    value = _field(msg, (name,), where)
    try:
        return int(value)
    except (TypeError, ValueError):
        raise InputError(f"{where}: field '{name}' must be an integer, got {value!r}") from None


def _bytes(data: Any, where: str) -> np.ndarray:
    """A 1-D uint8 view of a message's ``data`` field (copy only where unavoidable)."""
    if isinstance(data, np.ndarray):
        flat = data.reshape(-1)
        if flat.dtype == np.uint8:
            return flat
        if flat.dtype.itemsize == 1 or flat.dtype.kind in "SV":
            return np.ascontiguousarray(flat).view(np.uint8).reshape(-1)
        raise InputError(f"{where}: image data must be uint8 bytes, got a {data.dtype} array")
    if isinstance(data, str):
        raise InputError(f"{where}: image data must be bytes, got a str")
    try:
        return np.frombuffer(data, dtype=np.uint8)
    except (TypeError, ValueError, BufferError):
        pass
    try:
        return np.frombuffer(bytes(data), dtype=np.uint8)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{where}: image data must be bytes, got {type(data).__name__}") from None


def _pixels(image: Any, where: str, dtype: type[np.generic], channels: int) -> np.ndarray:
    """Decode a ``sensor_msgs/Image`` payload into a native, owned H×W(×C) array."""
    height = _int(image, "height", where)
    width = _int(image, "width", where)
    step = _int(image, "step", where)
    bigendian = bool(getattr(image, "is_bigendian", 0))
    if height <= 0 or width <= 0:
        raise InputError(f"{where}: image is empty ({width}×{height} px)")
    pixel = np.dtype(dtype).itemsize * channels
    row_bytes = width * pixel
    if step < row_bytes:
        raise InputError(
            f"{where}: step {step} is smaller than width·bytes per pixel = {width}·{pixel}"
            f" = {row_bytes}"
        )
    raw = _bytes(_field(image, ("data",), where), where)
    needed = height * step
    if raw.size < needed:
        raise InputError(
            f"{where}: image data has {raw.size} bytes, expected height·step = "
            f"{height}·{step} = {needed}"
        )
    rows = raw[:needed].reshape(height, step)
    if step != row_bytes:
        rows = rows[:, :row_bytes]
    stored = np.dtype(dtype).newbyteorder(">" if bigendian else "<")
    values = np.ascontiguousarray(rows).view(stored)
    # astype to the native dtype copies (and byte-swaps big-endian data) in one pass.
    out = values.astype(np.dtype(dtype), copy=True)
    return out.reshape(height, width, channels) if channels > 1 else out.reshape(height, width)


def _encoding(image: Any, where: str) -> str:
    return str(_field(image, ("encoding",), where))


# -- decode ---------------------------------------------------------------------------------


def stamp_ns(header: Any) -> int:
    """Nanoseconds of a ``std_msgs/Header`` (or of its ``stamp``): ``sec·1e9 + nanosec``.

    ROS 1 messages deserialised by rosbags have ``sec``/``nanosec`` too; rospy's ``secs``/``nsecs``
    are also accepted.
    """
    stamp = getattr(header, "stamp", header)
    sec = getattr(stamp, "sec", None)
    nanosec = getattr(stamp, "nanosec", None)
    if sec is None or nanosec is None:
        sec = getattr(stamp, "secs", None)
        nanosec = getattr(stamp, "nsecs", None)
    if sec is None or nanosec is None:
        raise InputError(
            f"expected a std_msgs/Header or builtin_interfaces/Time with sec and nanosec,"
            f" got {type(header).__name__}"
        )
    return int(sec) * _NS + int(nanosec)


@dataclass(frozen=True, eq=False)
class DisparityFrame:
    """A decoded ``stereo_msgs/DisparityImage``: the map and the fields the evaluation needs.

    ``disparity`` holds the values as published, including stereo_image_proc's invalid marker
    ``min_disparity − 1``. As the message defines them, the values are offset-corrected
    (``d = x_l − x_r − (cx_l − cx_r)``, so ``Z = f·T/d``) and valid inside
    ``[min_disparity, max_disparity]``, 0 and negative values included; :meth:`scoring` turns
    that into the core's convention. (Compared by identity: the array makes field-wise
    equality ambiguous.)
    """

    stamp: int
    frame_id: str
    disparity: np.ndarray
    f: float
    t: float
    min_disparity: float
    max_disparity: float
    delta_d: float

    @property
    def est_range(self) -> tuple[float, float]:
        """``(min_disparity, max_disparity)``, or ``(-inf, inf)`` when unset: valid then means > 0.

        Unset means both are 0, either is not finite, or ``max < min``.
        """
        low, high = self.min_disparity, self.max_disparity
        unset = (
            (low == 0 and high == 0)
            or not (math.isfinite(low) and math.isfinite(high))
            or high < low
        )
        return (-math.inf, math.inf) if unset else (low, high)

    @property
    def camera(self) -> Camera | None:
        """``Camera(f, |t|)`` when the message carries a focal length (> 0) and a baseline ≠ 0.

        A negative ``t`` is a sign convention of some drivers, not another geometry: its
        magnitude is the baseline (the caller warns once, see :attr:`negative_t`).
        """
        f, t = self.f, abs(self.t)
        if math.isfinite(f) and math.isfinite(t) and f > 0 and t > 0:
            return Camera(f, t)
        return None

    @property
    def negative_t(self) -> bool:
        """Whether ``t`` is negative (its magnitude is used as the baseline)."""
        return math.isfinite(self.t) and self.t < 0

    def scoring(self, camera: Camera | None) -> dict[str, Any]:
        """``est_range`` and ``est_offset`` for ``Evaluator.score``: the message as read.

        The one place where the message's values become the core's disparity ``x_l − x_r``. The
        core's convention is the datasets': ground truth ``x_l − x_r`` and depth
        ``Z = f·B/(d + doffs)``. The message's values are ``x_l − x_r + doffs`` (offset-corrected
        by ``doffs = cx_r − cx_l`` of the camera scored with, 0 without one), so the core scores
        ``value − doffs``; validity is tested on the values as published.
        """
        return {"est_range": self.est_range, "est_offset": camera.doffs if camera else 0.0}


def disparity_from_msg(msg: Any, topic: str = "") -> DisparityFrame:
    """Decode a ``stereo_msgs/msg/DisparityImage`` (ROS 2 or ROS 1 field names).

    The image must be ``32FC1``. ``valid_window`` is deliberately ignored: drivers often leave it
    wrong (zero, or the matcher's border only), so using it would discard good pixels; invalid
    pixels are recognised by their value instead (see :attr:`DisparityFrame.est_range`).
    """
    where = _where(topic, "DisparityImage")
    image = _field(msg, ("image",), where)
    encoding = _encoding(image, where)
    if encoding.upper() != "32FC1":
        raise InputError(f"{where}: image encoding is '{encoding}', expected 32FC1")
    disparity = _pixels(image, where, np.float32, 1)
    header = _field(msg, ("header",), where)
    return DisparityFrame(
        stamp=stamp_ns(header),
        frame_id=str(getattr(header, "frame_id", "")),
        disparity=disparity,
        f=float(_field(msg, ("f",), where)),
        t=float(_field(msg, ("t", "T"), where)),
        min_disparity=float(_field(msg, ("min_disparity",), where)),
        max_disparity=float(_field(msg, ("max_disparity",), where)),
        delta_d=float(getattr(msg, "delta_d", 0.0)),
    )


@dataclass(frozen=True, eq=False)
class ImageFrame:
    """A decoded ``sensor_msgs/Image``: float32/float64/uint16/uint8, H×W or H×W×3.

    Colour images keep the channel order their ``encoding`` names (rgb8 or bgr8).
    """

    stamp: int
    frame_id: str
    encoding: str
    array: np.ndarray


def image_from_msg(msg: Any, topic: str = "") -> ImageFrame:
    """Decode a ``sensor_msgs/msg/Image`` of one of :data:`IMAGE_ENCODINGS`."""
    where = _where(topic, "Image")
    raw_encoding = _encoding(msg, where)
    encoding = _CANONICAL.get(raw_encoding.lower())
    if encoding is None:
        raise InputError(
            f"{where}: image encoding '{raw_encoding}' is not supported; expected one of "
            + ", ".join(IMAGE_ENCODINGS)
        )
    dtype, channels = IMAGE_ENCODINGS[encoding]
    array = _pixels(msg, where, dtype, channels)
    header = _field(msg, ("header",), where)
    return ImageFrame(stamp_ns(header), str(getattr(header, "frame_id", "")), encoding, array)


def gt_disparity(
    frame: ImageFrame,
    kind: str = "disparity",
    scale: float | None = None,
    camera: Camera | None = None,
    topic: str = "",
) -> np.ndarray:
    """Ground-truth disparity (float32, px) from a decoded GT image.

    ``kind="disparity"``: float images as they are, 16-bit ones ``value / scale`` (default 256,
    KITTI). ``kind="depth"``: float images in metres, 16-bit ones ``value / scale`` (default
    1000: millimetres → metres), converted by ``d = f·B/Z − doffs``; ``Z ≤ 0`` or non-finite
    gives ``0`` (no ground truth). If ``scale`` is given for a float image, the values are
    divided by it as well. The baseline is converted to metres when the camera's unit is m, cm
    or mm; for other units the depth is taken to be in the camera's unit. A float32 disparity
    image without a scale is returned as it is: the frame's own array, not a copy.
    """
    where = _where(topic, "ground-truth Image")
    if kind not in _GT_KINDS:
        raise ConfigurationError(
            f"ground-truth kind must be one of {', '.join(_GT_KINDS)}, got '{kind}'"
        )
    array = frame.array
    if frame.encoding not in GT_ENCODINGS or array.ndim != 2:
        raise InputError(
            f"{where}: ground-truth encoding '{frame.encoding}' is not supported; expected "
            + ", ".join(GT_ENCODINGS)
        )
    is_int = array.dtype == np.uint16
    if scale is None:
        scale = _INT_SCALE[kind] if is_int else 1.0
    elif not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise ConfigurationError(f"ground-truth scale must be a number > 0, got {scale!r}")

    if kind == "disparity":
        if scale == 1.0:  # a float32 frame's own array (it owns a fresh copy), not a copy of it
            return array.astype(np.float32, copy=False)
        values = array.astype(np.float32)
        values /= np.float32(scale)
        return values

    if camera is None:
        raise CalibrationError(
            f"{where}: depth ground truth needs the camera (f, baseline);"
            " give the CameraInfo topics or a calibration"
        )
    depth = array.astype(np.float64)
    if scale != 1.0:
        depth /= scale
    fb = camera.f * camera.baseline * _METRES_PER_UNIT.get(camera.unit, 1.0)
    valid = np.isfinite(depth) & (depth > 0)
    disparity = np.zeros(depth.shape, dtype=np.float64)
    np.divide(fb, depth, out=disparity, where=valid)
    if camera.doffs:
        disparity[valid] -= camera.doffs
    return disparity.astype(np.float32)


def _projection(info: Any, where: str) -> np.ndarray:
    """The 3×4 projection ``P`` of a CameraInfo as 12 float64 values (``p`` or ``P``)."""
    raw = _field(info, ("p", "P"), where)
    try:
        values = np.asarray(raw, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise CalibrationError(f"{where}: P must be 12 numbers, got {raw!r}") from None
    if values.size != 12:
        raise CalibrationError(f"{where}: P must have 12 values, got {values.size}")
    return values


def _focal(values: np.ndarray, where: str) -> float:
    f = float(values[0])
    if not (math.isfinite(f) and f > 0):
        raise CalibrationError(
            f"{where} has P[0] = {f:g}: expected the focal length in px (> 0);"
            " is the camera calibrated?"
        )
    return f


def camera_from_infos(left: Any, right: Any, left_topic: str = "", right_topic: str = "") -> Camera:
    """The stereo camera from the left and right rectified ``sensor_msgs/CameraInfo``.

    ``f = P_left[0]``, ``B = (P_left[3] − P_right[3]) / P_right[0]`` (``−P_right[3] / P_right[0]``
    for ROS-rectified pairs, whose left ``P[3]`` is 0) and ``doffs = P_right[2] − P_left[2]``.
    """
    left_where = f"CameraInfo on {left_topic}" if left_topic else "the left CameraInfo"
    right_where = f"CameraInfo on {right_topic}" if right_topic else "the right CameraInfo"
    p_left = _projection(left, left_where)
    p_right = _projection(right, right_where)
    f = _focal(p_left, left_where)
    f_right = _focal(p_right, right_where)
    if abs(f_right - f) > 0.01 * f:
        raise CalibrationError(
            f"{left_where} and {right_where} have focal lengths P[0] = {f:g} and {f_right:g}:"
            " not a rectified stereo pair"
        )
    tx = float(p_right[3]) + 0.0  # + 0.0 turns −0 into 0 for the message
    tx_left = float(p_left[3])
    if not (math.isfinite(tx) and math.isfinite(tx_left)):
        raise CalibrationError(f"{right_where} has P[3] = {tx:g}: expected −f·B, a finite number")
    baseline = (tx_left - tx) / f_right
    if baseline == 0:
        raise CalibrationError(
            f"{right_where} has P[3] = {tx:g}: zero baseline; is this the right camera's info?"
        )
    if baseline < 0:
        raise CalibrationError(
            f"{right_where} has P[3] = {tx:g}: negative baseline {baseline:g};"
            " are the left and right CameraInfo topics swapped?"
        )
    doffs = float(p_right[2] - p_left[2])
    if not math.isfinite(doffs):
        raise CalibrationError(f"{right_where} has P[2] = {p_right[2]:g}: expected a finite cx")
    return Camera(f, baseline, doffs)


def camera_from_info_and_baseline(left: Any, baseline: float, topic: str = "") -> Camera:
    """The camera from one rectified CameraInfo (``f = P[0]``) and a known baseline."""
    where = f"CameraInfo on {topic}" if topic else "the CameraInfo"
    f = _focal(_projection(left, where), where)
    if not (isinstance(baseline, (int, float)) and math.isfinite(baseline) and baseline > 0):
        raise CalibrationError(f"baseline for {where} must be a number > 0, got {baseline!r}")
    return Camera(f, float(baseline))


#: ``sensor_msgs/PointField`` datatypes the x, y, z fields may have.
_POINT_FIELD_TYPES: dict[int, type[np.generic]] = {7: np.float32, 8: np.float64}
_POINT_FIELD_NAMES = {1: "INT8", 2: "UINT8", 3: "INT16", 4: "UINT16", 5: "INT32", 6: "UINT32"}


@dataclass(frozen=True, eq=False)
class CloudFrame:
    """A decoded ``sensor_msgs/PointCloud2``: its x, y, z as an N×3 array (N = width·height).

    Points keep their order (row by row for organised clouds); invalid points of clouds with
    ``is_dense`` false stay in as NaN (the projection skips non-finite points). The dtype is
    float32 when all three fields are float32, else float64.
    """

    stamp: int
    frame_id: str
    points: np.ndarray


def _point_field(fields: Any, name: str, where: str) -> tuple[int, type[np.generic]]:
    """Offset and dtype of the PointField called ``name``."""
    available = []
    for entry in fields:
        entry_name = str(_field(entry, ("name",), where))
        available.append(entry_name)
        if entry_name != name:
            continue
        datatype = _int(entry, "datatype", where)
        if datatype not in _POINT_FIELD_TYPES:
            shown = _POINT_FIELD_NAMES.get(datatype, str(datatype))
            raise InputError(
                f"{where}: field '{name}' has datatype {shown}, expected FLOAT32 (7) or FLOAT64 (8)"
            )
        count = int(getattr(entry, "count", 1) or 1)
        if count != 1:
            raise InputError(f"{where}: field '{name}' has count {count}, expected 1")
        return _int(entry, "offset", where), _POINT_FIELD_TYPES[datatype]
    raise InputError(
        f"{where}: the cloud has no '{name}' field (fields: {', '.join(available) or 'none'});"
        " expected x, y and z"
    )


def cloud_from_msg(msg: Any, topic: str = "") -> CloudFrame:
    """Decode the x, y, z of a ``sensor_msgs/msg/PointCloud2`` of any layout.

    Fields may sit at any offsets among others (intensity, ring, padding); ``point_step`` and
    ``row_step`` may include padding; organised (``height > 1``) and unorganised clouds and
    both endiannesses are read with one structured numpy view (no per-point Python loop).
    """
    where = _where(topic, "PointCloud2")
    height = _int(msg, "height", where)
    width = _int(msg, "width", where)
    point_step = _int(msg, "point_step", where)
    row_step = _int(msg, "row_step", where)
    bigendian = bool(getattr(msg, "is_bigendian", False))
    fields = _field(msg, ("fields",), where)
    layout = {name: _point_field(fields, name, where) for name in ("x", "y", "z")}
    header = _field(msg, ("header",), where)
    stamp, frame_id = stamp_ns(header), str(getattr(header, "frame_id", ""))
    all_float32 = all(dtype is np.float32 for _, dtype in layout.values())
    out_dtype = np.float32 if all_float32 else np.float64
    if height < 0 or width < 0:
        raise InputError(f"{where}: negative size {width}×{height}")
    for name, (offset, dtype) in layout.items():
        size = np.dtype(dtype).itemsize
        if offset < 0 or offset + size > point_step:
            raise InputError(
                f"{where}: field '{name}' at offset {offset} ({size} bytes) does not fit in "
                f"point_step {point_step}"
            )
    row_bytes = width * point_step
    if height > 1 and row_step < row_bytes:
        raise InputError(
            f"{where}: row_step {row_step} is smaller than width·point_step = "
            f"{width}·{point_step} = {row_bytes}"
        )
    step = max(row_step, row_bytes)
    raw = _bytes(_field(msg, ("data",), where), where)
    needed = (height - 1) * step + row_bytes if height and width else 0
    if raw.size < needed:
        raise InputError(
            f"{where}: data has {raw.size} bytes, expected at least {needed} for "
            f"{width}×{height} points of {point_step} bytes (row_step {row_step})"
        )
    if needed == 0:
        return CloudFrame(stamp, frame_id, np.empty((0, 3), dtype=out_dtype))
    order: Literal["<", ">"] = ">" if bigendian else "<"
    structured = np.dtype(
        {
            "names": list(layout),
            "formats": [np.dtype(dtype).newbyteorder(order) for _, dtype in layout.values()],
            "offsets": [offset for offset, _ in layout.values()],
            "itemsize": point_step,
        }
    )
    if height == 1 or step == row_bytes:
        packed = raw[: height * row_bytes]
    else:
        padded = np.zeros(height * step, dtype=np.uint8)
        padded[:needed] = raw[:needed]  # the last row's padding may be missing
        packed = padded.reshape(height, step)[:, :row_bytes].reshape(-1)
    records = np.ascontiguousarray(packed).view(structured)
    points = np.empty((records.shape[0], 3), dtype=out_dtype)
    for column, name in enumerate(layout):
        points[:, column] = records[name]
    return CloudFrame(stamp, frame_id, points)


def static_transforms_from_msg(msg: Any, topic: str = "") -> list[StaticTransform]:
    """The edges of a ``tf2_msgs/msg/TFMessage`` (``/tf_static``): parent, child, 4×4 matrix."""
    where = _where(topic, "TFMessage")
    edges = []
    for stamped in _field(msg, ("transforms",), where):
        header = _field(stamped, ("header",), where)
        transform = _field(stamped, ("transform",), where)
        translation = _field(transform, ("translation",), where)
        rotation = _field(transform, ("rotation",), where)
        try:
            matrix = matrix_from_pose(
                [float(translation.x), float(translation.y), float(translation.z)],
                [float(rotation.x), float(rotation.y), float(rotation.z), float(rotation.w)],
            )
        except (AttributeError, TypeError, ValueError):
            raise InputError(
                f"{where}: a transform needs translation x, y, z and rotation x, y, z, w"
            ) from None
        except CalibrationError as error:
            raise CalibrationError(f"{where}: {error}") from None
        parent = str(getattr(header, "frame_id", ""))
        child = str(_field(stamped, ("child_frame_id",), where))
        edges.append(StaticTransform(parent, child, matrix))
    return edges


@dataclass(frozen=True, eq=False)
class RectifiedView:
    """The left camera's geometry from its CameraInfo: what a cloud is projected with."""

    frame_id: str
    width: int
    height: int
    rectification: np.ndarray
    projection: np.ndarray


def rectified_camera_from_info(info: Any, topic: str = "") -> RectifiedView:
    """Frame, size, rectification ``R`` (3×3) and projection ``P`` (3×4) of a CameraInfo."""
    where = f"CameraInfo on {topic}" if topic else "the left CameraInfo"
    projection = _projection(info, where).reshape(3, 4)
    raw = getattr(info, "r", None)
    if raw is None:
        raw = getattr(info, "R", None)
    rectification = np.eye(3)
    if raw is not None:
        values = np.asarray(raw, dtype=np.float64).reshape(-1)
        # An all-zero R is what an uncalibrated driver publishes: treat it as the identity.
        if values.size == 9 and values.any():
            rectification = check_rotation(values.reshape(3, 3), f"{where}: R")
        elif values.size != 9:
            raise CalibrationError(f"{where}: R must have 9 values, got {values.size}")
    header = _field(info, ("header",), where)
    return RectifiedView(
        frame_id=str(getattr(header, "frame_id", "")),
        width=_int(info, "width", where),
        height=_int(info, "height", where),
        rectification=rectification,
        projection=projection,
    )
