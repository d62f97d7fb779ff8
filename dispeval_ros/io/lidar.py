"""LiDAR files: KITTI Velodyne scans, KITTI LiDAR–camera calibration and extrinsic files.

- A Velodyne ``.bin`` is raw little-endian float32 ``x, y, z, reflectance`` rows (no header).
- KITTI calibration comes in two formats holding the same numbers: the object format (one file:
  ``P2``, ``P3``, ``R0_rect``, ``Tr_velo_to_cam``) and the raw format (``calib_cam_to_cam.txt``
  with ``P_rect_02``, ``P_rect_03``, ``R_rect_00``, and ``calib_velo_to_cam.txt`` with ``R`` and
  ``T``). :func:`read_lidar_calib` reads either into a :class:`LidarCalibration`.
- An extrinsic file (``--extrinsic``) holds a 4×4 (or 3×4) matrix or ``x y z qx qy qz qw``.

Every problem raises a one-line :class:`~dispeval_ros.errors.CalibrationError` or
:class:`~dispeval_ros.errors.InputError` naming the file.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.projection import rectified_projection
from dispeval_ros.core.transforms import rigid_matrix
from dispeval_ros.errors import CalibrationError, InputError
from dispeval_ros.io.calib import _kitti_fields, _numbers
from dispeval_ros.io.files import PathLike, _read_bytes

#: Files of the KITTI raw calibration, in the recording day's folder.
RAW_CAM_TO_CAM = "calib_cam_to_cam.txt"
RAW_VELO_TO_CAM = "calib_velo_to_cam.txt"


def read_velodyne_bin(path: PathLike) -> np.ndarray:
    """The x, y, z (N×3 float32) of a KITTI Velodyne scan (N×4 float32 rows)."""
    file = Path(path)
    data = _read_bytes(file, "LiDAR scan")
    if len(data) % 16:
        raise InputError(
            f"{file}: a KITTI scan is rows of 4 float32 (16 bytes), but the file has "
            f"{len(data)} bytes (not a multiple of 16)"
        )
    return np.frombuffer(data, dtype="<f4").reshape(-1, 4)[:, :3].astype(np.float32)


@dataclass(frozen=True, eq=False)
class LidarCalibration:
    """LiDAR → camera extrinsic (4×4), left rectification (3×3), left and right ``P`` (3×4)."""

    extrinsic: np.ndarray
    rectification: np.ndarray
    left: np.ndarray
    right: np.ndarray

    @property
    def matrix(self) -> np.ndarray:
        """``P_left · R · T``: LiDAR points to homogeneous left-image pixels."""
        return rectified_projection(self.extrinsic, self.rectification, self.left)

    @property
    def camera(self) -> Camera:
        """The stereo camera: ``f = P_left[0,0]``, ``B = (P_left[0,3] − P_right[0,3]) / f``."""
        f = float(self.left[0, 0])
        if not f > 0:
            raise CalibrationError(f"the left projection's focal length must be > 0, got {f:g}")
        baseline = float(self.left[0, 3] - self.right[0, 3]) / f
        if not baseline > 0:
            raise CalibrationError(
                f"baseline (P_left[0,3] − P_right[0,3]) / f must be > 0, got {baseline:g}"
            )
        return Camera(f, baseline, float(self.right[0, 2] - self.left[0, 2]))

    def ros_view(self) -> tuple[np.ndarray, float, float]:
        """The calibration as ROS publishes a rectified pair: extrinsic, ``cx``, ``cy``.

        ROS's left CameraInfo has ``R = I`` and ``P = K·[I | 0]``; KITTI's ``P2 = K·[I | t]``
        and ``R0_rect`` are folded into the returned LiDAR → left-camera extrinsic, so that
        ``K·[I | 0]·extrinsic`` equals :attr:`matrix`.
        """
        k = self.left[:, :3]
        shift = np.eye(4)
        shift[:3, 3] = np.linalg.solve(k, self.left[:, 3])
        rect = np.eye(4)
        rect[:3, :3] = self.rectification
        return shift @ rect @ self.extrinsic, float(k[0, 2]), float(k[1, 2])


def _text(file: Path) -> str:
    try:
        return _read_bytes(file, "calibration").decode("utf-8-sig")
    except UnicodeDecodeError:
        raise CalibrationError(f"{file}: calibration file must be text") from None
    except InputError as error:
        raise CalibrationError(str(error)) from None


def _matrix_of(fields: dict[str, str], file: Path, name: str, shape: tuple[int, int]) -> np.ndarray:
    if name not in fields:
        raise CalibrationError(f"{file}: missing field '{name}' (KITTI calibration)")
    count = shape[0] * shape[1]
    values = _numbers(fields[name], file, name, count, f"({shape[0]}×{shape[1]} matrix)")
    return np.asarray(values, dtype=np.float64).reshape(shape)


def _rigid(matrix: np.ndarray, file: Path, name: str) -> np.ndarray:
    try:
        return rigid_matrix(matrix, name)
    except CalibrationError as error:
        raise CalibrationError(f"{file}: {error}") from None


def read_lidar_calib(path: PathLike) -> LidarCalibration:
    """KITTI LiDAR calibration from an object-format file or a raw-format folder (or file).

    ``path`` is an object-format ``calib.txt`` (``P2``, ``P3``, ``R0_rect``,
    ``Tr_velo_to_cam``), or a folder holding ``calib_cam_to_cam.txt`` and
    ``calib_velo_to_cam.txt`` (or one of those two files: the other is looked for beside it).
    """
    location = Path(path)
    if location.is_dir():
        folder = location
    elif location.name in (RAW_CAM_TO_CAM, RAW_VELO_TO_CAM):
        folder = location.parent
    else:
        text = _text(location)
        fields = _kitti_fields(text)
        if "Tr_velo_to_cam" not in fields and "Tr_velo_cam" in fields:
            fields["Tr_velo_to_cam"] = fields["Tr_velo_cam"]
        return LidarCalibration(
            extrinsic=_rigid(
                _matrix_of(fields, location, "Tr_velo_to_cam", (3, 4)), location, "Tr_velo_to_cam"
            ),
            rectification=_matrix_of(fields, location, "R0_rect", (3, 3)),
            left=_matrix_of(fields, location, "P2", (3, 4)),
            right=_matrix_of(fields, location, "P3", (3, 4)),
        )
    cam_file, velo_file = folder / RAW_CAM_TO_CAM, folder / RAW_VELO_TO_CAM
    for file in (cam_file, velo_file):
        if not file.is_file():
            raise CalibrationError(
                f"{file}: KITTI raw calibration file missing (a raw calibration needs "
                f"{RAW_CAM_TO_CAM} and {RAW_VELO_TO_CAM})"
            )
    cam = _kitti_fields(_text(cam_file))
    velo = _kitti_fields(_text(velo_file))
    extrinsic = np.eye(4)
    extrinsic[:3, :3] = _matrix_of(velo, velo_file, "R", (3, 3))
    extrinsic[:3, 3] = _matrix_of(velo, velo_file, "T", (3, 1))[:, 0]
    return LidarCalibration(
        extrinsic=_rigid(extrinsic, velo_file, "R|T"),
        rectification=_matrix_of(cam, cam_file, "R_rect_00", (3, 3)),
        left=_matrix_of(cam, cam_file, "P_rect_02", (3, 4)),
        right=_matrix_of(cam, cam_file, "P_rect_03", (3, 4)),
    )


_NUMBER_SPLIT = re.compile(r"[\s,;\[\]]+")


def read_extrinsic(path: PathLike) -> np.ndarray:
    """The LiDAR → camera transform in a text file.

    16 or 12 numbers (a 4×4 or 3×4 matrix, row-major) or 7 (``x y z qx qy qz qw``); text after
    ``#`` is a comment.

    The matrix maps points in the cloud's frame into the left camera's (optical) frame.
    """
    file = Path(path)
    text = _text(file)
    lines = [line.split("#", 1)[0] for line in text.splitlines()]
    tokens = [token for token in _NUMBER_SPLIT.split(" ".join(lines)) if token]
    try:
        values = [float(token) for token in tokens]
    except ValueError:
        raise CalibrationError(
            f"{file}: an extrinsic file holds only numbers (a 4×4 matrix or "
            f"'x y z qx qy qz qw'), found {' '.join(tokens)[:60]!r}"
        ) from None
    try:
        return rigid_matrix(values, "the extrinsic")
    except CalibrationError as error:
        raise CalibrationError(f"{file}: {error}") from None
