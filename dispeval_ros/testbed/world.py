"""What the synthetic cameras see and the rig that sees it: boxes, lane lines, world, rig.

The world is a ground plane, axis-aligned boxes (vehicles, walls, poles, buildings) and an
optional far wall. World axes are metres: ``x`` right, ``y`` up (the ground is ``y = 0``), ``z``
forward. Both cameras look along ``+z`` with identical intrinsics and ``doffs = 0`` (a
ROS-rectified pair); the right camera sits ``baseline`` metres to the right of the left one.
Plain records, so scenes can be built and moved without rendering (the LiDAR model reads them).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from dispeval_ros.core.camera import Camera

# Surface codes of View.surface: -1 nothing (sky), 0 ground, 1 far wall, 2 + i box i.
NOTHING = -1
GROUND = 0
FAR_WALL = 1
FIRST_BOX = 2

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Box:
    """An axis-aligned box from corner ``lo`` to corner ``hi`` (world metres).

    ``albedo`` is the mean brightness (0..1), ``contrast`` the texture's amplitude,
    ``texture_scale`` multiplies the texture's wavelengths, ``stripe_period`` (metres, 0 = none)
    adds vertical stripes to the side and front faces, ``texture_id`` picks the patch of
    procedural texture painted on the box (in box coordinates, so a moving box carries its
    texture along), and ``velocity`` (m/s) moves the box in a sequence (see :meth:`at`).
    """

    lo: Vec3
    hi: Vec3
    albedo: float = 0.5
    contrast: float = 0.3
    texture_scale: float = 1.0
    stripe_period: float = 0.0
    texture_id: int = 0
    velocity: Vec3 = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not all(a < b for a, b in zip(self.lo, self.hi, strict=True)):
            raise ValueError(
                f"box corners must satisfy lo < hi on every axis: {self.lo}, {self.hi}"
            )

    def at(self, time: float) -> Box:
        """Return the box moved by ``velocity · time``."""
        if self.velocity == (0.0, 0.0, 0.0) or time == 0:
            return self
        shift = [v * time for v in self.velocity]
        lo = (self.lo[0] + shift[0], self.lo[1] + shift[1], self.lo[2] + shift[2])
        hi = (self.hi[0] + shift[0], self.hi[1] + shift[1], self.hi[2] + shift[2])
        return replace(self, lo=lo, hi=hi)


@dataclass(frozen=True)
class LaneLine:
    """A painted line on the ground along ``z`` at ``x`` (metres); dashed when ``period > 0``."""

    x: float
    width: float = 0.15
    dash: float = 3.0
    period: float = 0.0


@dataclass(frozen=True)
class World:
    """What the cameras see: a textured ground plane, boxes and an optional far wall.

    ``ground_bands`` are ``(x_lo, x_hi, albedo)`` strips of the ground with another albedo
    (sidewalks, a median); ``far_wall_z`` places a textured wall ``z = far_wall_z`` facing the
    cameras (``None``: no wall, rays above the horizon see sky). ``far_wall_backdrop`` makes the
    wall a painted backdrop standing in for sky and horizon: the images show its texture (so
    matchers behave as before a real far scene), but it has no ground truth (depth and
    disparity ``inf``, as KITTI leaves its sky without GT) and a LiDAR gets no return from it.
    ``seed`` chooses the textures.
    """

    boxes: tuple[Box, ...] = ()
    ground_albedo: float = 0.45
    ground_contrast: float = 0.3
    ground_texture_scale: float = 1.0
    ground_bands: tuple[tuple[float, float, float], ...] = ()
    lane_lines: tuple[LaneLine, ...] = ()
    far_wall_z: float | None = None
    far_wall_albedo: float = 0.6
    far_wall_contrast: float = 0.3
    far_wall_texture_scale: float = 20.0
    far_wall_backdrop: bool = False
    seed: int = 0

    def at(self, time: float) -> World:
        """Return the world at ``time`` seconds: every box moved by its velocity."""
        return replace(self, boxes=tuple(box.at(time) for box in self.boxes))


@dataclass(frozen=True)
class StereoRig:
    """A rectified stereo pair: pinhole intrinsics shared by both views, and its pose.

    ``position`` is the left camera's optical centre (world metres); the right camera is at
    ``position + (baseline, 0, 0)``. ``velocity`` (m/s) moves the rig in a sequence.
    """

    width: int
    height: int
    f: float
    cx: float
    cy: float
    baseline: float
    position: Vec3 = (0.0, 1.2, 0.0)
    velocity: Vec3 = (0.0, 0.0, 0.0)

    @property
    def camera(self) -> Camera:
        """The :class:`Camera` record (``doffs = 0``) for depth conversions."""
        return Camera(f=float(self.f), baseline=float(self.baseline))

    @property
    def right_position(self) -> Vec3:
        """The right camera's optical centre."""
        x, y, z = self.position
        return (x + self.baseline, y, z)

    def at(self, time: float) -> StereoRig:
        """Return the rig at ``time`` seconds: moved by ``velocity · time``."""
        x, y, z = self.position
        vx, vy, vz = self.velocity
        return replace(self, position=(x + vx * time, y + vy * time, z + vz * time))
