"""LiDAR ground truth: projection speed against a plain numpy baseline, and the filter's effect.

Prints timings and ratios only (machines are noisy: nothing here is asserted). Run:

    python bench/bench_lidar.py [--repeat N]

Clouds: the real KITTI scans of ``kitti-lidar`` (118–123 k points, 1242×375) when the shared
data is present (``DISPEVAL_DATA`` or ``../shared/data``), and a synthetic 120 k-point scan of
the test-bed drive (64 beams, ±15°, 0.165° azimuth) at 1242×375. Both implementations project
with the z-buffer and the parallax filter (default 7×7 window, gap 0.1) and must give the same
map. The process is pinned to one core.
Then the filter's effect: points removed, on KITTI the agreement with the official GT, and on
``make-bag``'s synthetic drive (620×188, its 32-beam LiDAR, 10 frames) the kept points that
disagree by more than 1 px with the camera's exact ray cast.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np
from bench_scoring import timed  # this folder is on sys.path when run as a script

from dispeval_ros.core import Camera
from dispeval_ros.core.projection import CloudFilter, project_cloud, rectified_projection
from dispeval_ros.io.files import read_disparity
from dispeval_ros.io.lidar import read_lidar_calib, read_velodyne_bin
from dispeval_ros.testbed import driving_setup, driving_world_at, render_stereo
from dispeval_ros.testbed.lidar import LidarModel, check_scan, lidar_to_camera, simulate_scan

DATA = (
    Path(os.environ.get("DISPEVAL_DATA") or Path(__file__).resolve().parents[2] / "shared" / "data")
    / "kitti-lidar"
)
KITTI_FRAMES = ("000010", "000043", "000112", "000150")
SHAPE = (375, 1242)


def numpy_projection(
    points: np.ndarray,
    matrix: np.ndarray,
    shape: tuple[int, int],
    camera: Camera,
    window: int,
    gap: float,
) -> np.ndarray:
    """The straightforward numpy way: project, z-buffer by sorting, a min filter by shifts."""
    height, width = shape
    xyz = points.astype(np.float64)
    uvw = xyz @ matrix[:, :3].T + matrix[:, 3]
    front = np.isfinite(uvw).all(axis=1) & (uvw[:, 2] > 0)
    w = uvw[front, 2]
    col = np.floor(uvw[front, 0] / w + 0.5)
    row = np.floor(uvw[front, 1] / w + 0.5)
    inside = (col >= 0) & (col < width) & (row >= 0) & (row < height)
    index = (row[inside] * width + col[inside]).astype(np.int64)
    depth_values = w[inside]
    order = np.argsort(-depth_values, kind="stable")  # far first: the nearest is written last
    depth = np.full(height * width, np.inf)
    depth[index[order]] = depth_values[order]
    depth = depth.reshape(shape)
    keep = np.isfinite(depth)
    if window > 1:
        half = window // 2
        padded = np.pad(depth, half, constant_values=np.inf)
        nearest = np.full(shape, np.inf)
        for dy in range(window):
            for dx in range(window):
                np.minimum(nearest, padded[dy : dy + height, dx : dx + width], out=nearest)
        keep &= ~(nearest < depth / (1.0 + gap))
    disparity = np.zeros(shape, np.float32)
    disparity[keep] = camera.fb / depth[keep] - camera.doffs
    return disparity


def clouds() -> list[tuple[str, np.ndarray, np.ndarray, Camera, np.ndarray | None]]:
    """(name, points, matrix, camera, official GT or None) of every benchmark cloud."""
    found = []
    if (DATA / "raw-calib-2011_09_26").is_dir():
        calibration = read_lidar_calib(DATA / "raw-calib-2011_09_26")
        folder = DATA / "kitti2015-with-velodyne"
        for frame in KITTI_FRAMES:
            points = read_velodyne_bin(folder / "velodyne_points" / f"{frame}.bin")
            official = read_disparity(folder / "gt" / "disp_occ_0" / f"{frame}.png")
            found.append(
                (f"KITTI {frame}", points, calibration.matrix, calibration.camera, official)
            )
    else:
        print(f"(no KITTI scans at {DATA}: synthetic cloud only)")
    world, rig = driving_setup(SHAPE[1], SHAPE[0], 10.0, 0)
    model = LidarModel(beams=64, azimuth_step=0.165)
    world_t, rig_t = driving_world_at(world, rig, 0.0)
    points = simulate_scan(world_t, rig_t, model)
    k = np.array([[rig.f, 0, rig.cx, 0], [0, rig.f, rig.cy, 0], [0, 0, 1, 0]])
    matrix = rectified_projection(lidar_to_camera(rig_t, model), np.eye(3), k)
    found.append(("synthetic drive", points, matrix, rig.camera, None))
    return found


def main() -> None:
    """Time both implementations on every cloud, then print the filter's effect."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20, help="timed runs per case")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    chosen = CloudFilter()
    print(f"projection into {SHAPE[1]}×{SHAPE[0]} with the filter on ({chosen}), one core")
    print(f"{'cloud':<16} {'points':>8} {'numba ms':>9} {'numpy ms':>9} {'ratio':>6}")
    effects = []
    for name, points, matrix, camera, official in clouds():
        fast = project_cloud(points, matrix, SHAPE, camera, chosen)
        plain = numpy_projection(points, matrix, SHAPE, camera, chosen.window, chosen.gap)
        if not np.allclose(fast.disparity, plain, rtol=1e-6, atol=0):
            raise SystemExit(f"{name}: the numba and numpy maps differ")
        case = (points, matrix, SHAPE, camera)
        numba_ms = timed(lambda case=case: project_cloud(*case, chosen), args.repeat)
        numpy_ms = timed(
            lambda case=case: numpy_projection(*case, chosen.window, chosen.gap),
            max(3, args.repeat // 4),
        )
        ratio = numpy_ms / numba_ms
        print(f"{name:<16} {len(points):>8} {numba_ms:>9.2f} {numpy_ms:>9.2f} {ratio:>5.1f}×")
        effects.append((name, points, matrix, camera, official))

    print("\nthe parallax filter's effect (points in the image after the z-buffer)")
    header = f"{'cloud':<16} {'in image':>9} {'removed':>8} {'share':>6}"
    print(header + "   vs official GT: >3 px off, filter off → on")
    for name, points, matrix, camera, official in effects:
        off = project_cloud(points, matrix, SHAPE, camera, CloudFilter(0))
        on = project_cloud(points, matrix, SHAPE, camera, chosen)
        line = f"{name:<16} {off.kept:>9} {on.removed:>8} {100 * on.removed / off.kept:>5.1f}%"
        if official is not None:
            shares = []
            for projected in (off, on):
                both = (projected.disparity > 0) & (official > 0)
                error = np.abs(projected.disparity[both] - official[both])
                shares.append(100 * float((error > 3).mean()))
            line += f"   {shares[0]:.2f}% → {shares[1]:.2f}%"
        print(line)
    synthetic_check(chosen)


def synthetic_check(chosen: CloudFilter) -> None:
    """Kept points off the exact ray cast by > 1 px, filter off and on (make-bag's drive)."""
    world, rig = driving_setup(620, 188, 10.0, 0)
    totals = {str(f): [0, 0, 0, 0] for f in (CloudFilter(0), chosen)}
    for index in range(0, 30, 3):
        world_t, rig_t = driving_world_at(world, rig, index / 10.0)
        pixel_gt = render_stereo(world_t, rig_t, stamp=index / 10.0).gt_left
        for option in (CloudFilter(0), chosen):
            check = check_scan(world_t, rig_t, cloud_filter=option, pixel_gt=pixel_gt)
            total = totals[str(option)]
            for i, value in enumerate(
                (check.kept, check.removed, check.off_exact, check.off_pixel)
            ):
                total[i] += value
    print("\nsynthetic drive (make-bag's LiDAR, 10 frames): kept points off by > 1 px")
    print(f"{'filter':<8} {'kept':>7} {'removed':>8} {'vs exact ray':>13} {'vs pixel centre':>16}")
    for name, (kept, removed, exact, pixel) in totals.items():
        print(
            f"{name:<8} {kept:>7} {removed:>8} {100 * exact / kept:>12.2f}% "
            f"{100 * pixel / kept:>15.2f}%"
        )


if __name__ == "__main__":
    main()
