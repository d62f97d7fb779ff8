"""The test-bed's synthetic drive written as a KITTI raw drive, with its exact GT and motion.

``eval --scene DRIVE --temporal`` needs a dense GT of consecutive frames and ``--egomotion``
the camera's pose at every frame; a KITTI raw drive (:mod:`~dispeval_ros.io.kitti_raw`) is
the layout that carries poses, so the synthetic drive is written as one:

- ``DAY/calib_cam_to_cam.txt``, ``calib_velo_to_cam.txt``, ``calib_imu_to_velo.txt``: the
  rig's exact intrinsics (``P_rect_02 = K·[I | 0]``, ``R_rect_00 = I``), the simulated LiDAR's
  mounting, and the oxts unit at the LiDAR (``imu_to_velo = I``);
- ``DAY/DRIVE_sync/{image_02,image_03,velodyne_points,oxts}/data`` with ``timestamps.txt``:
  the rendered pair, the LiDAR scan, and the pose;
- ``DRIVE_sync/gt/disp_occ_0/FRAME.png``: the exact GT map where KITTI 2015 publishes its own
  beside a scan (KITTI's 16-bit PNG, value/256), so ``--gt-source auto`` scores against it
  (``scan``: against the projected LiDAR scan instead);
- ``estimates/NAME/FRAME.png``: the test-bed's OpenCV methods on every frame.

The rig never turns, so the poses are exact translations: each oxts file holds the LiDAR's
position encoded (the inverse of the devkit's Mercator ``convertOxtsToPose``) from a fixed
first latitude, with roll = pitch = yaw = 0; its velocities are the rig's.
"""

from __future__ import annotations

import dataclasses
import math
import shutil
from collections.abc import Callable
from datetime import datetime, timedelta
from pathlib import Path

import cv2
import numpy as np

from dispeval_ros.errors import InputError
from dispeval_ros.io.files import write_disparity_png16
from dispeval_ros.io.kitti_raw import EARTH_RADIUS, RAW_IMU_TO_VELO, STREAMS, TIMESTAMPS
from dispeval_ros.io.lidar import RAW_CAM_TO_CAM, RAW_VELO_TO_CAM
from dispeval_ros.testbed import (
    StereoRig,
    default_methods,
    driving_setup,
    driving_world_at,
    render_stereo,
)
from dispeval_ros.testbed.lidar import LidarModel, lidar_to_camera, simulate_scan

DAY = "2000_01_01"
DRIVE = f"{DAY}_drive_0001_sync"
GT_FOLDER = Path("gt") / "disp_occ_0"
"""Where the exact GT map of each frame goes in the drive (the scene loader's official GT)."""
ESTIMATES = "estimates"
FIRST_LATITUDE = 49.0
FIRST_LONGITUDE = 8.4
FIRST_ALTITUDE = 110.0
START = "2000-01-01 12:00:00"
"""The stamp of frame 0 (frames follow every 1/fps s)."""
OXTS_VALUES = 30
"""Values per oxts line (lat lon alt roll pitch yaw vn ve vf vl vu … orimode)."""


def _matrix(values: np.ndarray) -> str:
    return " ".join(repr(float(v)) for v in np.asarray(values, dtype=np.float64).ravel())


def calibration_texts(rig: StereoRig, model: LidarModel) -> dict[str, str]:
    """The three calibration files of the day folder, exact (full float precision)."""
    k = np.array([[rig.f, 0.0, rig.cx], [0.0, rig.f, rig.cy], [0.0, 0.0, 1.0]])
    left = np.hstack([k, np.zeros((3, 1))])
    right = left.copy()
    right[0, 3] = -rig.f * rig.baseline
    size = f"{float(rig.width)!r} {float(rig.height)!r}"
    velo = lidar_to_camera(rig, model)
    synthetic = "calib_time: synthetic (dispeval make-scene)"
    cam_to_cam = [
        synthetic,
        f"S_rect_00: {size}",
        f"R_rect_00: {_matrix(np.eye(3))}",
        f"P_rect_00: {_matrix(left)}",
        f"S_rect_02: {size}",
        f"P_rect_02: {_matrix(left)}",
        f"S_rect_03: {size}",
        f"P_rect_03: {_matrix(right)}",
    ]
    rigid = {
        RAW_VELO_TO_CAM: (velo[:3, :3], velo[:3, 3]),
        RAW_IMU_TO_VELO: (np.eye(3), np.zeros(3)),
    }
    texts = {RAW_CAM_TO_CAM: "\n".join(cam_to_cam) + "\n"}
    for name, (rotation, translation) in rigid.items():
        texts[name] = f"{synthetic}\nR: {_matrix(rotation)}\nT: {_matrix(translation)}\n"
    return texts


def lidar_position(rig: StereoRig, model: LidarModel) -> np.ndarray:
    """The LiDAR's origin in LiDAR axes (x forward, y left, z up) of the world, metres."""
    x, y, z = model.origin(rig)
    return np.array([z, -x, y])


def oxts_line(position: np.ndarray, first: np.ndarray, velocity: np.ndarray) -> str:
    """An oxts line whose ``convertOxtsToPose`` pose is a translation by ``position − first``.

    The inverse of :func:`~dispeval_ros.io.kitti_raw.oxts_poses`: Mercator scale of the
    first latitude, ``lon = tx·180 / (scale·π·er)``, ``lat = 360/π·atan(exp(ty / (scale·er)))
    − 90``; frame 0 is at :data:`FIRST_LATITUDE`, :data:`FIRST_LONGITUDE`.
    """
    scale = math.cos(math.radians(FIRST_LATITUDE))
    x0 = scale * FIRST_LONGITUDE * math.pi * EARTH_RADIUS / 180.0
    y0 = scale * EARTH_RADIUS * math.log(math.tan(math.pi * (90.0 + FIRST_LATITUDE) / 360.0))
    dx, dy, dz = (float(v) for v in np.subtract(position, first))
    lon = (x0 + dx) * 180.0 / (scale * math.pi * EARTH_RADIUS)
    lat = 360.0 / math.pi * math.atan(math.exp((y0 + dy) / (scale * EARTH_RADIUS))) - 90.0
    forward, left, up = (float(v) for v in velocity)  # yaw 0: forward is east, left north
    values = [lat, lon, FIRST_ALTITUDE + dz, 0.0, 0.0, 0.0, left, forward, forward, left, up]
    values += [0.0] * (OXTS_VALUES - len(values) - 4) + [4, 10, 4, 4]
    return " ".join(repr(v) if isinstance(v, float) else str(v) for v in values)


def _stamp(index: int, fps: float) -> str:
    """Frame ``index``'s stamp as KITTI writes them (``YYYY-MM-DD HH:MM:SS.fffffffff``)."""
    nanoseconds = round(index * 1e9 / fps)
    seconds, fraction = divmod(nanoseconds, 1_000_000_000)
    moment = datetime.strptime(START, "%Y-%m-%d %H:%M:%S") + timedelta(seconds=seconds)
    return f"{moment:%Y-%m-%d %H:%M:%S}.{fraction:09d}"


def write_drive(
    out: Path,
    frames: int,
    width: int,
    height: int,
    fps: float,
    seed: int,
    *,
    traffic: bool = True,
    progress: Callable[[int], None] | None = None,
) -> dict[str, object]:
    """Write the synthetic drive under ``out`` (see the module docstring); what was written.

    The frames are :func:`~dispeval_ros.testbed.make_driving_sequence`'s; without ``traffic``
    the moving vehicles are left out, so every surface is static (the ego-motion residual of
    the true disparity is then its exactness alone). ``out`` must not exist; on any failure
    nothing is left behind.
    """
    if out.exists():
        raise InputError(f"{out}: exists; remove it or choose another path")
    try:
        return _write(out, (frames, width, height, fps, seed), traffic, progress)
    except BaseException:
        shutil.rmtree(out, ignore_errors=True)
        raise


def _write(
    out: Path,
    drive_options: tuple[int, int, int, float, int],
    traffic: bool,
    progress: Callable[[int], None] | None,
) -> dict[str, object]:
    frames, width, height, fps, seed = drive_options
    model = LidarModel()
    world, rig = driving_setup(width, height, fps, seed)
    if not traffic:
        world = dataclasses.replace(world, boxes=())  # the roadside is static and added per frame
    day = out / DAY
    drive = day / DRIVE
    folders = {name: drive / name / "data" for name in STREAMS}
    methods = default_methods(width)
    estimates = {m.name: out / ESTIMATES / m.name for m in methods}
    for folder in [*folders.values(), drive / GT_FOLDER, *estimates.values()]:
        folder.mkdir(parents=True)
    for name, text in calibration_texts(rig, model).items():
        (day / name).write_text(text, encoding="utf-8")
    first = lidar_position(rig, model)
    velocity = np.array([rig.velocity[2], -rig.velocity[0], rig.velocity[1]])
    stamps = []
    for index in range(frames):
        stem = f"{index:010d}"
        world_t, rig_t = driving_world_at(world, rig, index / fps)  # as make_driving_sequence
        frame = render_stereo(world_t, rig_t, stamp=index / fps, noise_seed=[seed, index])
        for name, image in (("image_02", frame.left), ("image_03", frame.right)):
            if not cv2.imwrite(str(folders[name] / f"{stem}.png"), image):
                raise InputError(f"{folders[name] / stem}.png: cannot write PNG")
        scan = simulate_scan(world_t, rig_t, model)
        rows = np.column_stack([scan, np.ones(len(scan), np.float32)]).astype("<f4")
        (folders["velodyne_points"] / f"{stem}.bin").write_bytes(rows.tobytes())
        line = oxts_line(lidar_position(rig_t, model), first, velocity)
        (folders["oxts"] / f"{stem}.txt").write_text(line + "\n", encoding="utf-8")
        write_disparity_png16(drive / GT_FOLDER / f"{stem}.png", frame.gt_left)
        for method in methods:
            estimate = method.compute(frame.left, frame.right)
            write_disparity_png16(estimates[method.name] / f"{stem}.png", estimate)
        stamps.append(_stamp(index, fps))
        if progress is not None:
            progress(index + 1)
    text = "\n".join(stamps) + "\n"
    for name in STREAMS:
        (drive / name / TIMESTAMPS).write_text(text, encoding="utf-8")
    for extra in ("timestamps_start.txt", "timestamps_end.txt"):  # one instant per scan
        (drive / "velodyne_points" / extra).write_text(text, encoding="utf-8")
    return {
        "drive": str(drive),
        "frames": frames,
        "size": [width, height],
        "fps": fps,
        "seed": seed,
        "traffic": traffic,
        "camera": {"f": rig.f, "baseline": rig.baseline, "cx": rig.cx, "cy": rig.cy},
        "gt": str(drive / GT_FOLDER),
        "estimates": {name: str(folder) for name, folder in estimates.items()},
    }
