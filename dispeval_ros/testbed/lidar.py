"""A simulated spinning LiDAR in the synthetic world: exact ray casting, like the cameras.

The LiDAR has ``beams`` lasers spread evenly over a vertical field ``±vertical_fov`` degrees,
fires every ``azimuth_step`` degrees over a full turn, and sits ``offset`` metres from the left
camera (right, up, forward in world axes): by default above and behind it, as on a car roof,
so that it sees background the camera does not (parallax occlusions). Every ray is intersected
exactly with the ground, the far wall and every box; rays that hit nothing, a backdrop (the
sky stand-in ``World.far_wall_backdrop``) or come back from beyond ``max_range`` give no point.
The whole scan is taken at one instant (no motion distortion), so the only differences from
the camera's exact GT are the LiDAR's viewpoint and sampling.

Points are in the LiDAR's frame (REP 103: ``x`` forward, ``y`` left, ``z`` up);
:func:`lidar_to_camera` gives the transform into the left camera's optical frame (``x`` right,
``y`` down, ``z`` forward).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dispeval_ros.core.projection import CloudFilter, project_cloud, rectified_projection
from dispeval_ros.testbed.world import StereoRig, Vec3, World

# Columns: the LiDAR's axes (x forward, y left, z up) in world axes (x right, y up, z forward).
_LIDAR_AXES = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
# Rows: the optical frame's axes (x right, y down, z forward) in world axes.
_OPTICAL_AXES = np.diag([1.0, -1.0, 1.0])


@dataclass(frozen=True)
class LidarModel:
    """Beams, fields of view, range, and the mounting offset from the left camera (metres)."""

    beams: int = 32
    vertical_fov: float = 15.0
    azimuth_step: float = 0.2
    max_range: float = 120.0
    offset: Vec3 = (0.3, 0.4, -0.3)
    horizontal_fov: float = 360.0
    """Degrees of the turn published, centred forward (drivers can crop a scan to save bandwidth)."""

    def directions(self) -> np.ndarray:
        """Unit ray directions (N×3, world axes), beam by beam, each over the horizontal field."""
        elevations = np.radians(np.linspace(-self.vertical_fov, self.vertical_fov, self.beams))
        half = min(self.horizontal_fov, 360.0) / 2
        azimuths = np.radians(np.arange(-half, half, self.azimuth_step))
        elevation, azimuth = np.meshgrid(elevations, azimuths, indexing="ij")
        cos_e = np.cos(elevation)
        # azimuth 0 looks forward (+z), positive turns left (−x), as a LiDAR's yaw.
        world = np.stack(
            [-cos_e * np.sin(azimuth), np.sin(elevation), cos_e * np.cos(azimuth)], axis=-1
        )
        return world.reshape(-1, 3)

    def origin(self, rig: StereoRig) -> Vec3:
        """The LiDAR's position in the world for a rig pose."""
        x, y, z = rig.position
        dx, dy, dz = self.offset
        return (x + dx, y + dy, z + dz)


def _hit_distance(world: World, origin: Vec3, directions: np.ndarray) -> np.ndarray:
    """Distance along each unit ray to the nearest surface (``inf``: nothing, or a backdrop)."""
    ox, oy, oz = origin
    dx, dy, dz = directions[:, 0], directions[:, 1], directions[:, 2]
    best = np.full(directions.shape[0], np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        if oy > 0:
            ground = -oy / dy
            best = np.where((dy < 0) & (ground > 0), ground, best)
        wall_z = None if world.far_wall_backdrop else world.far_wall_z
        if wall_z is not None and wall_z > oz:
            wall = (wall_z - oz) / dz
            best = np.where((dz > 0) & (wall < best), wall, best)
        for box in world.boxes:
            t_near = np.full(directions.shape[0], -np.inf)
            t_far = np.full(directions.shape[0], np.inf)
            for axis, o, d in ((0, ox, dx), (1, oy, dy), (2, oz, dz)):
                lo, hi = box.lo[axis], box.hi[axis]
                t1 = (lo - o) / d
                t2 = (hi - o) / d
                parallel = d == 0
                inside = lo <= o <= hi
                near = np.where(parallel, -np.inf if inside else np.inf, np.minimum(t1, t2))
                far = np.where(parallel, np.inf if inside else -np.inf, np.maximum(t1, t2))
                t_near = np.maximum(t_near, near)
                t_far = np.minimum(t_far, far)
            hit = (t_near <= t_far) & (t_near > 0) & (t_near < best)
            best = np.where(hit, t_near, best)
    return best


def simulate_scan(world: World, rig: StereoRig, model: LidarModel | None = None) -> np.ndarray:
    """One LiDAR scan (N×3 float32, the LiDAR's frame) of ``world`` with the rig at its pose."""
    chosen = model or LidarModel()
    directions = chosen.directions()
    distance = _hit_distance(world, chosen.origin(rig), directions)
    keep = np.isfinite(distance) & (distance <= chosen.max_range)
    world_points = directions[keep] * distance[keep, None]
    return (world_points @ _LIDAR_AXES).astype(np.float32)


def lidar_to_camera(rig: StereoRig, model: LidarModel | None = None) -> np.ndarray:
    """The 4×4 transform from the LiDAR's frame to the left camera's optical frame."""
    chosen = model or LidarModel()
    transform = np.eye(4)
    transform[:3, :3] = _OPTICAL_AXES @ _LIDAR_AXES
    transform[:3, 3] = _OPTICAL_AXES @ np.asarray(chosen.offset, dtype=np.float64)
    return transform


def rig_motion(rig: StereoRig, later: StereoRig) -> np.ndarray:
    """The left camera's pose at ``later`` in its optical frame at ``rig`` (4×4).

    The rig never turns, so the motion is the step between the two optical centres in the
    optical axes: the exact ego-motion a drive's /tf carries (:func:`lidar_to_camera`'s axes).
    """
    motion = np.eye(4)
    motion[:3, 3] = _OPTICAL_AXES @ np.subtract(later.position, rig.position)
    return motion


@dataclass(frozen=True)
class ScanCheck:
    """How a projected scan compares with what the left camera sees exactly.

    ``kept``: pixels with a LiDAR value; ``removed``: pixels the filter emptied; ``off_exact``:
    kept values more than ``tolerance`` px from the disparity of the camera's exact ray through
    the point's own (sub-pixel) projection — the camera does not see that point;
    ``off_pixel``: the same against the exact disparity at the pixel centre (``pixel_gt``),
    which adds the rounding of points near object edges.
    """

    kept: int
    removed: int
    off_exact: int
    off_pixel: int


def check_scan(
    world: World,
    rig: StereoRig,
    model: LidarModel | None = None,
    cloud_filter: CloudFilter | None = None,
    pixel_gt: np.ndarray | None = None,
    tolerance: float = 1.0,
) -> ScanCheck:
    """Simulate, project and compare one scan with the exact ray cast (see :class:`ScanCheck`)."""
    chosen = model or LidarModel()
    scan = simulate_scan(world, rig, chosen).astype(np.float64)
    k = np.array([[rig.f, 0, rig.cx, 0], [0, rig.f, rig.cy, 0], [0, 0, 1, 0]])
    matrix = rectified_projection(lidar_to_camera(rig, chosen), np.eye(3), k)
    shape = (rig.height, rig.width)
    projected = project_cloud(scan, matrix, shape, rig.camera, cloud_filter)
    # The winning point of every kept pixel, and the camera's exact ray through it.
    uvw = np.column_stack([scan, np.ones(len(scan))]) @ matrix.T
    front = uvw[:, 2] > 0
    u = uvw[front, 0] / uvw[front, 2]
    v = uvw[front, 1] / uvw[front, 2]
    col, row = np.floor(u + 0.5).astype(int), np.floor(v + 0.5).astype(int)
    inside = (col >= 0) & (col < rig.width) & (row >= 0) & (row < rig.height)
    u, v, col, row, w = u[inside], v[inside], col[inside], row[inside], uvw[front, 2][inside]
    value = projected.disparity[row, col]
    winner = (value > 0) & np.isclose(rig.camera.fb / w, value, rtol=1e-6)
    _, first = np.unique(row[winner] * rig.width + col[winner], return_index=True)
    u, v = u[winner][first], v[winner][first]
    row, col, value = row[winner][first], col[winner][first], value[winner][first]
    directions = np.column_stack([(u - rig.cx) / rig.f, -(v - rig.cy) / rig.f, np.ones(len(u))])
    norms = np.linalg.norm(directions, axis=1)
    distance = _hit_distance(world, rig.position, directions / norms[:, None])
    exact = rig.camera.fb / (distance / norms)
    off_pixel = 0
    if pixel_gt is not None:
        off_pixel = int((np.abs(value - pixel_gt[row, col]) > tolerance).sum())
    return ScanCheck(
        kept=len(value),
        removed=projected.removed,
        off_exact=int((np.abs(value - exact) > tolerance).sum()),
        off_pixel=off_pixel,
    )
