"""ROS messages from numpy, without ROS: what ``make_bag`` and the test-bed write.

The encode functions build messages of a given rosbags typestore (ROS 2 or ROS 1), as the ROS 2
drivers publish them, to write bags. They are the inverse of the decoders in
:mod:`dispeval_ros.io.messages`, kept apart because only the bag writers need them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.transforms import StaticTransform, pose_from_matrix
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.messages import _CANONICAL, _NS, IMAGE_ENCODINGS

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = [
    "camera_info_to_msg",
    "cloud_to_msg",
    "disparity_to_msg",
    "image_to_msg",
    "tf_static_to_msg",
]


def _build(typestore: Typestore, typename: str, values: Mapping[str, Any]) -> Any:
    """A message of ``typename`` from ``values`` keyed by lower-case (ROS 2) field names.

    Fields are matched case-insensitively so ROS 1 stores (``T``, ``P``, ``K``) work too; a
    ROS 1 header's ``seq`` is 0.
    """
    try:
        cls = typestore.types[typename]
        names = [name for name, _ in typestore.fielddefs[typename][1]]
    except KeyError:
        raise ConfigurationError(f"the typestore has no message type {typename}") from None
    kwargs: dict[str, Any] = {}
    for name in names:
        if name in values:
            kwargs[name] = values[name]
        elif name.lower() in values:
            kwargs[name] = values[name.lower()]
        elif name == "seq":
            kwargs[name] = 0
        else:
            raise ConfigurationError(f"cannot fill field '{name}' of {typename}")
    return cls(**kwargs)


def _header(typestore: Typestore, stamp: int, frame_id: str) -> Any:
    sec, nanosec = divmod(int(stamp), _NS)
    time = _build(typestore, "builtin_interfaces/msg/Time", {"sec": sec, "nanosec": nanosec})
    return _build(typestore, "std_msgs/msg/Header", {"stamp": time, "frame_id": frame_id})


def _roi(typestore: Typestore, width: int = 0, height: int = 0) -> Any:
    return _build(
        typestore,
        "sensor_msgs/msg/RegionOfInterest",
        {"x_offset": 0, "y_offset": 0, "height": height, "width": width, "do_rectify": False},
    )


def _image(typestore: Typestore, array: np.ndarray, header: Any, encoding: str) -> Any:
    """A ``sensor_msgs/Image`` of a little-endian, unpadded array (data is a uint8 view)."""
    dtype, channels = IMAGE_ENCODINGS[encoding]
    # A copy, so the message does not change when the caller reuses its array.
    data = np.array(array, dtype=np.dtype(dtype).newbyteorder("<"), order="C", copy=True)
    height, width = data.shape[:2]
    return _build(
        typestore,
        "sensor_msgs/msg/Image",
        {
            "header": header,
            "height": height,
            "width": width,
            "encoding": encoding,
            "is_bigendian": 0,
            "step": width * channels * data.itemsize,
            "data": data.reshape(-1).view(np.uint8),
        },
    )


def disparity_to_msg(
    typestore: Typestore,
    disparity: np.ndarray,
    stamp_ns: int,
    frame_id: str,
    f: float,
    t: float,
    min_disparity: float,
    max_disparity: float,
    delta_d: float = 1.0 / 16.0,
    doffs: float = 0.0,
) -> Any:
    """A ``stereo_msgs/msg/DisparityImage`` as ROS 2 stereo_image_proc publishes it.

    ``disparity``, ``min_disparity`` and ``max_disparity`` are ``x_l − x_r`` (a matcher's
    output); the message carries them offset-corrected as it defines, ``+ doffs``
    (``doffs = cx_r − cx_l``), so its range stays the range of its values. 32FC1
    little-endian image with ``step = 4·width``; ``valid_window`` covers the whole image; the
    image's header equals the message's.
    """
    array = np.asarray(disparity)
    if array.ndim != 2 or array.size == 0:
        raise ConfigurationError(
            f"disparity must be a non-empty H×W array, got shape {array.shape}"
        )
    if doffs:  # in float32, as the values: a value on a bound stays on it
        shift = np.float32(doffs)
        array = array.astype(np.float32) + shift
        min_disparity = float(np.float32(min_disparity) + shift)
        max_disparity = float(np.float32(max_disparity) + shift)
    header = _header(typestore, stamp_ns, frame_id)
    height, width = array.shape
    return _build(
        typestore,
        "stereo_msgs/msg/DisparityImage",
        {
            "header": header,
            "image": _image(typestore, array.astype(np.float32, copy=False), header, "32FC1"),
            "f": float(f),
            "t": float(t),
            "valid_window": _roi(typestore, width, height),
            "min_disparity": float(min_disparity),
            "max_disparity": float(max_disparity),
            "delta_d": float(delta_d),
        },
    )


def image_to_msg(
    typestore: Typestore, array: np.ndarray, stamp_ns: int, frame_id: str, encoding: str
) -> Any:
    """A ``sensor_msgs/msg/Image`` of one of :data:`IMAGE_ENCODINGS` (little-endian, unpadded).

    Float encodings accept any real array; integer encodings need integer values in range.
    """
    name = _CANONICAL.get(encoding.lower())
    if name is None:
        raise ConfigurationError(
            f"image encoding '{encoding}' is not supported; expected one of "
            + ", ".join(IMAGE_ENCODINGS)
        )
    dtype, channels = IMAGE_ENCODINGS[name]
    values = np.asarray(array)
    if values.ndim == 3 and values.shape[2] == 1 and channels == 1:
        values = values[:, :, 0]
    expected_ndim = 2 if channels == 1 else 3
    if (
        values.ndim != expected_ndim
        or values.size == 0
        or (channels > 1 and values.shape[2] != channels)
    ):
        shape = "H×W" if channels == 1 else f"H×W×{channels}"
        raise ConfigurationError(
            f"{name} needs a non-empty {shape} array, got shape {values.shape}"
        )
    if np.issubdtype(dtype, np.integer) and values.dtype != dtype:
        info = np.iinfo(np.dtype(dtype))
        if not (np.issubdtype(values.dtype, np.integer) or values.dtype == np.bool_):
            raise ConfigurationError(f"{name} needs an integer array, got {values.dtype}")
        if values.size and (values.min() < info.min or values.max() > info.max):
            raise ConfigurationError(f"{name} values must be in [{info.min}, {info.max}]")
    header = _header(typestore, stamp_ns, frame_id)
    return _image(typestore, values, header, name)


def camera_info_to_msg(
    typestore: Typestore,
    camera: Camera,
    width: int,
    height: int,
    stamp_ns: int,
    frame_id: str,
    right: bool,
    cx: float | None = None,
    cy: float | None = None,
) -> Any:
    """A rectified pinhole ``sensor_msgs/msg/CameraInfo`` of the left or right camera.

    ``K = [f 0 cx; 0 f cy; 0 0 1]``, ``R = I``, ``D = 0`` (plumb_bob) and ``P = [K | t]`` with
    ``t = (−f·B, 0, 0)`` for the right camera. The principal point defaults to the image centre
    ``(width/2 − 0.5, height/2 − 0.5)``; the right camera's ``cx`` is ``cx + doffs``.
    """
    cx_left = width / 2.0 - 0.5 if cx is None else float(cx)
    cy_ = height / 2.0 - 0.5 if cy is None else float(cy)
    f = float(camera.f)
    cx_ = cx_left + camera.doffs if right else cx_left
    tx = -f * camera.baseline if right else 0.0
    return _build(
        typestore,
        "sensor_msgs/msg/CameraInfo",
        {
            "header": _header(typestore, stamp_ns, frame_id),
            "height": int(height),
            "width": int(width),
            "distortion_model": "plumb_bob",
            "d": np.zeros(5, dtype=np.float64),
            "k": np.array([f, 0, cx_, 0, f, cy_, 0, 0, 1], dtype=np.float64),
            "r": np.eye(3, dtype=np.float64).reshape(-1),
            "p": np.array([f, 0, cx_, tx, 0, f, cy_, 0, 0, 0, 1, 0], dtype=np.float64),
            "binning_x": 0,
            "binning_y": 0,
            "roi": _roi(typestore),
        },
    )


def cloud_to_msg(
    typestore: Typestore,
    points: np.ndarray,
    stamp_ns: int,
    frame_id: str,
    intensity: np.ndarray | None = None,
) -> Any:
    """An unorganised little-endian ``sensor_msgs/msg/PointCloud2`` of float32 x, y, z.

    With ``intensity``, a fourth float32 field ``intensity`` (as Velodyne drivers publish:
    ``point_step`` 16). Non-finite points are kept (``is_dense`` is then false).
    """
    xyz = np.asarray(points, dtype=np.float32)
    if xyz.ndim != 2 or xyz.shape[1] != 3:
        raise ConfigurationError(f"a point cloud must be an N×3 array, got shape {xyz.shape}")
    names = ["x", "y", "z"] + ([] if intensity is None else ["intensity"])
    record = np.zeros(
        xyz.shape[0], dtype=np.dtype({"names": names, "formats": ["<f4"] * len(names)})
    )
    for column, name in enumerate(("x", "y", "z")):
        record[name] = xyz[:, column]
    if intensity is not None:
        record["intensity"] = np.asarray(intensity, dtype=np.float32).reshape(-1)
    fields = [
        _build(
            typestore,
            "sensor_msgs/msg/PointField",
            {"name": name, "offset": 4 * index, "datatype": 7, "count": 1},
        )
        for index, name in enumerate(names)
    ]
    point_step = 4 * len(names)
    return _build(
        typestore,
        "sensor_msgs/msg/PointCloud2",
        {
            "header": _header(typestore, stamp_ns, frame_id),
            "height": 1,
            "width": xyz.shape[0],
            "fields": fields,
            "is_bigendian": False,
            "point_step": point_step,
            "row_step": point_step * xyz.shape[0],
            "data": record.view(np.uint8).reshape(-1).copy(),
            "is_dense": bool(np.isfinite(xyz).all()),
        },
    )


def tf_static_to_msg(typestore: Typestore, transforms: list[StaticTransform], stamp_ns: int) -> Any:
    """A ``tf2_msgs/msg/TFMessage`` of static transforms (each: parent → child pose)."""
    stamped = []
    for transform in transforms:
        translation, quaternion = pose_from_matrix(transform.matrix)
        x, y, z = (float(v) for v in translation)
        qx, qy, qz, qw = (float(v) for v in quaternion)
        stamped.append(
            _build(
                typestore,
                "geometry_msgs/msg/TransformStamped",
                {
                    "header": _header(typestore, stamp_ns, transform.parent),
                    "child_frame_id": transform.child,
                    "transform": _build(
                        typestore,
                        "geometry_msgs/msg/Transform",
                        {
                            "translation": _build(
                                typestore, "geometry_msgs/msg/Vector3", {"x": x, "y": y, "z": z}
                            ),
                            "rotation": _build(
                                typestore,
                                "geometry_msgs/msg/Quaternion",
                                {"x": qx, "y": qy, "z": qz, "w": qw},
                            ),
                        },
                    ),
                },
            )
        )
    return _build(typestore, "tf2_msgs/msg/TFMessage", {"transforms": stamped})
