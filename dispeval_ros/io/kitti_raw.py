"""KITTI raw drives, in the layout the raw ``*_sync.zip`` files unpack to.

``DATE/DRIVE_sync/{image_02,image_03,velodyne_points,oxts}/data/NNNNNNNNNN.{png,png,bin,txt}``
with one ``timestamps.txt`` per stream (``YYYY-MM-DD HH:MM:SS.fffffffff``, 9-digit fractions
that :func:`datetime.strptime` cannot parse), and the day's calibration one level up
(``DATE/calib_cam_to_cam.txt``, ``calib_velo_to_cam.txt``, ``calib_imu_to_velo.txt``).

:func:`open_drive` checks the whole drive before anything is read (every stream present, the
same frames in each, one stamp per frame, the calibration complete), so a bad folder is one
line and nothing written. The velodyne stamp is ``velodyne_points/timestamps.txt``: the moment
the rotating scanner faced forward (the camera trigger), halfway between
``timestamps_start.txt`` and ``timestamps_end.txt``. :func:`oxts_poses` is the devkit's
``convertOxtsToPose``: the GPS/IMU unit's pose relative to its first sample;
:func:`drive_motion` carries those poses to the left camera as ``/tf`` does and looks them up
at the images' stamps (2–13 ms off the oxts samples' on the shared drive).
"""

from __future__ import annotations

import bisect
import calendar
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dispeval_ros.core.transform_history import TransformHistory, format_stamp
from dispeval_ros.core.transforms import StaticTransform, invert_rigid
from dispeval_ros.errors import CalibrationError, InputError, LayoutError
from dispeval_ros.io.calib import _kitti_fields
from dispeval_ros.io.lidar import (
    RAW_CAM_TO_CAM,
    LidarCalibration,
    _matrix_of,
    _rigid,
    _text,
    read_lidar_calib,
)

#: The streams of a synced drive and the extension of their ``data/`` files, in reading order.
STREAMS = {"image_02": ".png", "image_03": ".png", "velodyne_points": ".bin", "oxts": ".txt"}
RAW_IMU_TO_VELO = "calib_imu_to_velo.txt"
TIMESTAMPS = "timestamps.txt"
EARTH_RADIUS = 6378137.0
"""The devkit's ``er`` (m): Mercator scale of the oxts positions."""

_STAMP = re.compile(r"^(\d{4})-(\d{2})-(\d{2})[ T](\d{2}):(\d{2}):(\d{2})(?:\.(\d{1,9}))?$")
_STAMP_FORM = "'YYYY-MM-DD HH:MM:SS.fffffffff'"
#: oxts values a pose needs: lat, lon, alt, roll, pitch, yaw.
_POSE_VALUES = 6


def parse_stamp(text: str) -> int | None:
    """Nanoseconds since the epoch of a KITTI stamp (read as UTC), None if it is not one.

    Integer arithmetic throughout: a float of 1.3e9 s keeps only about 0.2 µs.
    """
    match = _STAMP.match(text.strip())
    if match is None:
        return None
    year, month, day, hour, minute, second = (int(g) for g in match.groups()[:6])
    if not (1 <= month <= 12 and 1 <= day <= 31 and hour < 24 and minute < 60 and second < 61):
        return None
    seconds = calendar.timegm((year, month, day, hour, minute, second, 0, 0, 0))
    return seconds * 1_000_000_000 + int((match.group(7) or "").ljust(9, "0"))


def read_timestamps(file: Path) -> list[int]:
    """Every stamp of a ``timestamps.txt`` (ns), blank lines skipped; a bad line is an error."""
    stamps = []
    try:
        lines = file.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as exc:
        raise InputError(f"{file}: cannot read ({exc.strerror or exc})") from None
    for number, line in enumerate(lines, 1):
        if not line.strip():
            continue
        stamp = parse_stamp(line)
        if stamp is None:
            raise InputError(
                f"{file}: line {number} is not a timestamp: expected {_STAMP_FORM}, "
                f"got {line.strip()[:40]!r}"
            )
        stamps.append(stamp)
    return stamps


@dataclass(frozen=True)
class RawStream:
    """One stream of a drive: its ``data/`` files and their stamps (ns), frame by frame."""

    name: str
    files: list[Path]
    stamps: list[int]


@dataclass(frozen=True, eq=False)
class RawDrive:
    """A checked KITTI raw drive: four streams of the same frames and the day's calibration."""

    folder: Path
    frames: list[str]
    """The frames' file stems (``0000000000`` …), the same in every stream."""
    streams: dict[str, RawStream]
    calibration: LidarCalibration
    calib_folder: Path
    """Where the day's ``calib_*.txt`` are (the day folder, or the drive's own)."""
    imu_to_velo: np.ndarray
    """IMU (oxts unit) → Velodyne, 4×4: maps IMU-frame points into the LiDAR frame."""

    @property
    def numbers(self) -> list[int]:
        """Each frame's number (the file stem as an integer)."""
        return [int(frame) for frame in self.frames]


def is_drive(folder: Path) -> bool:
    """A KITTI raw drive: any of its streams has a ``data/`` folder."""
    return any((folder / stream / "data").is_dir() for stream in STREAMS)


def drives_in(folder: Path) -> list[Path]:
    """The drives of a day folder (``*_sync`` subfolders that are drives), sorted."""
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if p.name.endswith("_sync") and is_drive(p))


def is_raw_source(folder: Path) -> bool:
    """A drive folder or a day folder holding drives: what :func:`resolve_drive` accepts."""
    return folder.is_dir() and (is_drive(folder) or bool(drives_in(folder)))


def resolve_drive(folder: Path) -> Path:
    """The drive a ``--scene`` folder names: itself, or the only drive of a day folder.

    A day folder with several drives is ambiguous (each drive is one sequence, one bag):
    refused, listing them.
    """
    if is_drive(folder):
        return folder
    drives = drives_in(folder)
    if len(drives) == 1:
        return drives[0]
    if not drives:
        raise LayoutError(f"{folder}: not a KITTI raw drive or day folder (no *_sync drive)")
    names = ", ".join(d.name for d in drives)
    raise LayoutError(
        f"{folder}: a day folder with {len(drives)} drives ({names}); give one drive folder "
        "(each drive is one bag)"
    )


def _stream(folder: Path, name: str, suffix: str) -> RawStream:
    data = folder / name / "data"
    if not data.is_dir():
        present = sorted(s + "/" for s in STREAMS if (folder / s / "data").is_dir())
        raise LayoutError(
            f"{folder}: no {name}/data/ folder: a KITTI raw drive needs "
            f"{', '.join(STREAMS)}, each with data/ and {TIMESTAMPS} (found "
            f"{', '.join(present) or 'none'})"
        )
    files = sorted(p for p in data.iterdir() if p.suffix.lower() == suffix and p.stem.isdigit())
    if not files:
        raise LayoutError(f"{data}: no NNNNNNNNNN{suffix} files")
    stamps_file = folder / name / TIMESTAMPS
    if not stamps_file.is_file():
        raise LayoutError(f"{stamps_file}: missing (one stamp per frame of {name})")
    stamps = read_timestamps(stamps_file)
    if len(stamps) != len(files):
        raise InputError(
            f"{stamps_file}: {len(stamps)} timestamps for the {len(files)} files of {name}/data"
        )
    return RawStream(name, files, stamps)


def _same_frames(folder: Path, streams: dict[str, RawStream]) -> list[str]:
    """The frames of the first stream, which every other stream must have too."""
    first, *others = streams.values()
    frames = [f.stem for f in first.files]
    for stream in others:
        stems = [f.stem for f in stream.files]
        if stems == frames:
            continue
        missing = sorted(set(frames) - set(stems)) or sorted(set(stems) - set(frames))
        short, long = (stream, first) if len(stems) < len(frames) else (first, stream)
        shown = ", ".join(missing[:3]) + (" …" if len(missing) > 3 else "")
        raise InputError(
            f"{folder}: {stream.name} has {len(stems)} frames, {first.name} {len(frames)}: "
            f"frame(s) {shown} of {long.name} missing in {short.name}"
        )
    return frames


def _calib_folder(folder: Path) -> Path:
    """The drive's calibration: beside it (the day folder) or, failing that, inside it."""
    for candidate in (folder.parent, folder):
        if (candidate / RAW_CAM_TO_CAM).is_file():
            return candidate
    raise CalibrationError(
        f"{folder.parent / RAW_CAM_TO_CAM}: KITTI raw calibration missing (the day's "
        "calib_*.txt belong beside the drive folder)"
    )


def read_imu_to_velo(file: Path) -> np.ndarray:
    """``calib_imu_to_velo.txt`` (``R``, ``T``) as a 4×4 rigid transform."""
    if not file.is_file():
        raise CalibrationError(
            f"{file}: KITTI raw calibration file missing (the oxts pose needs IMU → Velodyne)"
        )
    fields = _kitti_fields(_text(file))
    matrix = np.eye(4)
    matrix[:3, :3] = _matrix_of(fields, file, "R", (3, 3))
    matrix[:3, 3] = _matrix_of(fields, file, "T", (3, 1))[:, 0]
    return _rigid(matrix, file, "R|T")


def open_drive(path: Path) -> RawDrive:
    """Check and index a drive (or a day folder holding one drive); reads no image or scan."""
    folder = resolve_drive(Path(path))
    streams = {name: _stream(folder, name, suffix) for name, suffix in STREAMS.items()}
    frames = _same_frames(folder, streams)
    calib = _calib_folder(folder)
    calibration = read_lidar_calib(calib)
    _ = calibration.camera  # f > 0 and B > 0, checked now rather than at the first frame
    imu_to_velo = read_imu_to_velo(calib / RAW_IMU_TO_VELO)
    return RawDrive(folder, frames, streams, calibration, calib, imu_to_velo)


def read_oxts(file: Path) -> np.ndarray:
    """The pose values of one oxts file: lat, lon (deg), alt (m), roll, pitch, yaw (rad)."""
    try:
        tokens = file.read_text(encoding="utf-8", errors="replace").split()
    except OSError as exc:
        raise InputError(f"{file}: cannot read ({exc.strerror or exc})") from None
    try:
        values = [float(token) for token in tokens[:_POSE_VALUES]]
    except ValueError:
        values = []
    if len(values) < _POSE_VALUES or not all(math.isfinite(v) for v in values):
        raise InputError(
            f"{file}: an oxts file starts with {_POSE_VALUES} numbers (lat lon alt roll pitch "
            f"yaw), got {' '.join(tokens[:_POSE_VALUES])[:60]!r}"
        )
    return np.asarray(values, dtype=np.float64)


def _rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``Rz(yaw) · Ry(pitch) · Rx(roll)``, as the devkit composes them."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
        math.cos(yaw), math.sin(yaw),
    )  # fmt: skip
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def oxts_poses(samples: np.ndarray) -> np.ndarray:
    """The devkit's ``convertOxtsToPose``: N×4×4 poses of the oxts unit, the first one I.

    Mercator scale from the first latitude; ``t = (scale·lon·π·er/180,
    scale·er·ln(tan(π·(90 + lat)/360)), alt)``, ``R = Rz(yaw)·Ry(pitch)·Rx(roll)``; every pose
    is ``T₀⁻¹·Tᵢ``, so it maps points of the unit's frame at sample i into its frame at the
    first sample (odom → base_link).
    """
    values = np.asarray(samples, dtype=np.float64).reshape(-1, _POSE_VALUES)
    scale = math.cos(math.radians(values[0, 0]))
    poses = np.empty((values.shape[0], 4, 4))
    for index, (lat, lon, alt, roll, pitch, yaw) in enumerate(values):
        pose = np.eye(4)
        pose[:3, :3] = _rotation(roll, pitch, yaw)
        pose[:3, 3] = (
            scale * lon * math.pi * EARTH_RADIUS / 180.0,
            scale * EARTH_RADIUS * math.log(math.tan(math.pi * (90.0 + lat) / 360.0)),
            alt,
        )
        poses[index] = pose
    return invert_rigid(poses[0]) @ poses


def _oxts_samples(drive: RawDrive) -> tuple[list[str | None], dict[int, np.ndarray]]:
    """Each oxts sample's one-line reason it is unusable (None if usable), the usable poses.

    The poses (:func:`oxts_poses`, the oxts unit's, relative to the first usable sample) are
    keyed by the sample's index. Unusable: an unreadable file, a latitude not within ±90° (the
    Mercator ``ln tan`` is undefined there), a stamp not after the previous usable sample's.
    """
    samples: dict[int, np.ndarray] = {}
    reasons: list[str | None] = []
    stream = drive.streams["oxts"]
    last: int | None = None
    for index, (file, stamp) in enumerate(zip(stream.files, stream.stamps, strict=True)):
        try:
            values = read_oxts(file)
            if not abs(values[0]) < 90:  # Mercator: the log of a negative tangent
                raise InputError(f"{file}: the latitude must be within ±90°, not a pose")
            if last is not None and stamp <= stream.stamps[last]:
                raise InputError(
                    f"{drive.folder / 'oxts' / TIMESTAMPS}: the stamp of {file.stem} "
                    f"({format_stamp(stamp)}) is not after that of {stream.files[last].stem} "
                    f"({format_stamp(stream.stamps[last])}), not a pose"
                )
        except InputError as error:
            reasons.append(str(error))
            continue
        samples[index], last = values, index
        reasons.append(None)
    if not samples:
        return reasons, {}
    poses = oxts_poses(np.stack(list(samples.values())))
    return reasons, dict(zip(samples, poses, strict=True))


def _camera_to_imu(drive: RawDrive) -> np.ndarray:
    """The left rectified camera's pose on the oxts unit: ``T_cam_imu⁻¹`` (base_link → camera).

    The camera (the one ``K·[I | 0]`` projects for: :meth:`LidarCalibration.ros_view`) sees
    IMU points through ``T_cam_imu = extrinsic · imu_to_velo``.
    """
    return invert_rigid(drive.calibration.ros_view()[0] @ drive.imu_to_velo)


def camera_poses(drive: RawDrive) -> list[np.ndarray | str]:
    """Each oxts sample's pose of the left rectified camera in the odometry frame, or why none.

    The oxts unit's pose (:func:`oxts_poses`) times ``T_cam_imu⁻¹`` (:func:`_camera_to_imu`),
    at the oxts sample's own stamp, so ``poses[t]⁻¹ · poses[t + k]`` is the pose of the camera
    at sample ``t + k`` in its frame at sample ``t``. An unusable sample gets the one-line
    reason instead (the other samples keep their poses: only relative poses count).
    ``eval --egomotion`` looks the poses up at the images' stamps: :func:`drive_motion`.
    """
    reasons, poses = _oxts_samples(drive)
    camera_to_imu = _camera_to_imu(drive)
    return [
        poses[index] @ camera_to_imu if reason is None else reason
        for index, reason in enumerate(reasons)
    ]


@dataclass(frozen=True)
class DriveMotion:
    """The camera's motion of a drive as ``/tf`` carries it, looked up at the left images' stamps.

    ``history``: the oxts poses as ``fixed → base`` at each usable sample's stamp and the mount
    ``base → camera`` (what ``make-bag`` writes on ``/tf`` and ``/tf_static``), so the motion
    between two frames is :meth:`TransformHistory.camera_motion` of their image stamps: each
    pose interpolated between the two oxts samples around the stamp, never extrapolated.
    """

    history: TransformHistory
    camera_frame: str
    stamps: list[int]
    """Each frame's left image stamp (ns)."""
    problems: list[str | None]
    """Per frame, why its pose cannot be looked up (an unusable oxts sample it lies beside)."""

    def between(self, first: int, second: int) -> np.ndarray:
        """The camera's pose at frame ``second`` in its frame at frame ``first`` (4×4).

        The convention of :func:`dispeval_ros.core.egomotion.camera_motion`. Raises the
        frame's problem as :class:`InputError`, or :class:`ExtrapolationError` for an image
        stamp outside the oxts samples.
        """
        for index in (first, second):
            problem = self.problems[index]
            if problem is not None:
                raise InputError(problem)
        return self.history.camera_motion(
            self.camera_frame, self.stamps[first], self.stamps[second]
        )


def drive_motion(drive: RawDrive, *, fixed: str, base: str, camera: str) -> DriveMotion:
    """The drive's :class:`DriveMotion`, its frames named ``fixed``, ``base`` and ``camera``.

    A frame whose image stamp lies between two usable oxts samples with an unusable one
    between them gets that sample's reason (the pose would be guessed across it); a stamp
    outside the usable samples is left to the lookup's :class:`ExtrapolationError`.
    """
    reasons, poses = _oxts_samples(drive)
    oxts = drive.streams["oxts"].stamps
    usable = sorted(poses)
    stamps = [oxts[index] for index in usable]
    history = TransformHistory(cache_ns=max(stamps[-1] - stamps[0], 1) if stamps else 1)
    history.add_static([StaticTransform(base, camera, _camera_to_imu(drive))])
    for index in usable:
        history.add(oxts[index], StaticTransform(fixed, base, poses[index]))
    images = list(drive.streams["image_02"].stamps)
    problems: list[str | None] = []
    for stamp in images:
        at = bisect.bisect_left(stamps, stamp)
        if at < len(stamps) and stamps[at] == stamp:
            problems.append(None)
            continue
        low = usable[at - 1] if at > 0 else -1
        high = usable[at] if at < len(usable) else len(reasons)
        problems.append(next((r for r in reasons[low + 1 : high] if r is not None), None))
    return DriveMotion(history, camera, images, problems)
