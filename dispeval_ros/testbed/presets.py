"""Ready-made scenes: the small static demo scene and the KITTI-like driving sequence.

Each preset is a seeded layout (:func:`scene_setup`, :func:`driving_setup`) and a renderer of
it, so tests can inspect the world a frame was rendered from.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import replace
from functools import lru_cache

import numpy as np

from dispeval_ros.testbed.render import StereoFrame, render_stereo
from dispeval_ros.testbed.world import Box, LaneLine, StereoRig, Vec3, World

# --------------------------------------------------------------------------------------------
# The demo scene


def scene_setup(
    width: int = 640, height: int = 400, seed: int = 0, baseline: float = 0.12
) -> tuple[World, StereoRig]:
    """World and rig of :func:`make_scene`: boxes from 1.5 m to 16 m before a wall at 30 m.

    The focal length is ``0.9·width``, so the nearest surface (1.5 m) has a disparity of
    ``0.9·width·baseline/1.5`` (46 px at 640 wide with the default 0.12 m baseline).
    """
    rng = np.random.default_rng([seed, 0x5CE7E])

    def jitter(amount: float) -> float:
        return float(rng.uniform(-amount, amount))

    def box(lo: Vec3, hi: Vec3, *, stripe_period: float = 0.0, texture_scale: float = 1.0) -> Box:
        return Box(
            lo=lo,
            hi=hi,
            albedo=0.35 + 0.35 * float(rng.random()),
            contrast=0.3 + 0.1 * float(rng.random()),
            texture_scale=texture_scale,
            stripe_period=stripe_period,
            texture_id=int(rng.integers(1 << 30)),
        )

    a, b, c = jitter(0.1), jitter(0.2), jitter(0.3)
    boxes = (
        # A crate close to the camera on the left (the nearest surface, 1.5 m).
        box((-0.95 + a, 0.0, 1.5), (-0.3 + a, 0.9 + jitter(0.1), 2.1)),
        # A small crate partly hiding the van behind it.
        box((0.45 + b, 0.0, 2.8), (1.0 + b, 0.6 + jitter(0.05), 3.3)),
        # A van-sized box whose left side face is seen obliquely.
        box((0.25, 0.0, 4.2 + b), (2.1, 1.6 + jitter(0.1), 8.0 + b), stripe_period=0.35),
        # A pole in front of a far block at 14 m.
        box((-1.55 + c, 0.0, 6.0), (-1.4 + c, 3.0, 6.15)),
        box((-4.5, 0.0, 14.0 + c), (-1.2, 3.0 + jitter(0.3), 16.0 + c), texture_scale=1.5),
    )
    world = World(
        boxes=boxes,
        ground_albedo=0.42,
        ground_contrast=0.32,
        far_wall_z=30.0,
        far_wall_texture_scale=2.5,
        seed=seed,
    )
    rig = StereoRig(
        width=width,
        height=height,
        f=0.9 * width,
        cx=(width - 1) / 2,
        cy=(height - 1) / 2,
        baseline=baseline,
        position=(-baseline / 2, 1.1, 0.0),
    )
    return world, rig


def make_scene(
    width: int = 640, height: int = 400, seed: int = 0, baseline: float = 0.12
) -> StereoFrame:
    """Render a small static scene: textured ground, five boxes at 1.5–14 m, a wall at 30 m.

    Every pixel has finite ground truth; boxes overlap in view, so there are occlusions and
    depth discontinuities. Disparities stay below ``0.072·width`` px (46 px at 640 wide).
    """
    world, rig = scene_setup(width, height, seed, baseline)
    return render_stereo(world, rig, noise_seed=[seed, 0])


# --------------------------------------------------------------------------------------------
# The driving sequence

KITTI_WIDTH, KITTI_HEIGHT = 1242, 375
KITTI_F, KITTI_CX, KITTI_CY = 721.5377, 609.5593, 172.854
CAMERA_HEIGHT = 1.65
NEAREST = 4.0  # metres: nothing in front comes closer (97 px disparity at KITTI size)
_BLOCK = 50.0  # metres of roadside generated from one seed block
_AHEAD = 300.0  # roadside generated this far ahead of the camera
# The background, kept this far ahead of the camera (like the sky: fixed), a backdrop: the
# images show it, its GT is unknown (a 0.43 px GT there made far points dominate SZE).
_FAR_WALL = 450.0

# Road across x (metres from the rig's centre): same-direction lanes at 0 and +3.5, a median,
# an oncoming lane at -6.5, sidewalks beyond the kerbs.
_LANE_LINES = (
    LaneLine(-1.75, width=0.15),
    LaneLine(1.75, dash=3.0, period=9.0),
    LaneLine(5.25, width=0.2),
    LaneLine(-4.75, width=0.15),
    LaneLine(-8.25, width=0.2),
)
_BANDS = ((-4.75, -1.75, 0.52), (5.35, 1e9, 0.58), (-1e9, -8.35, 0.58))


def driving_setup(
    width: int = 620, height: int = 188, fps: float = 10.0, seed: int = 0, baseline: float = 0.54
) -> tuple[World, StereoRig]:
    """World (at time 0, boxes with velocities) and rig of :func:`make_driving_sequence`.

    The world holds the traffic only; the static roadside is laid out in 50 m blocks, each
    from its own seed, and added per frame by :func:`driving_world_at`, so a sequence of any
    length stays cheap. Only vehicles move; they never come closer than ``NEAREST`` metres.
    """
    del fps  # the layout does not depend on the frame rate
    rng = np.random.default_rng([seed, 0xD21E])
    speed = float(rng.uniform(8.0, 12.0))
    f = KITTI_F * width / KITTI_WIDTH
    rig = StereoRig(
        width=width,
        height=height,
        f=f,
        cx=KITTI_CX * width / KITTI_WIDTH,
        cy=KITTI_CY * height / KITTI_HEIGHT,
        baseline=baseline,
        position=(-baseline / 2, CAMERA_HEIGHT, 0.0),
        velocity=(0.0, 0.0, speed),
    )
    world = World(
        boxes=_vehicles(rng, speed),
        ground_albedo=0.36,
        ground_contrast=0.34,
        ground_bands=_BANDS,
        lane_lines=_LANE_LINES,
        far_wall_z=_FAR_WALL,
        far_wall_albedo=0.7,
        far_wall_texture_scale=60.0,
        far_wall_backdrop=True,
        seed=seed,
    )
    return world, rig


def _car(x: float, z: float, rng: np.random.Generator, velocity: Vec3) -> Box:
    """Make a vehicle body centred on ``x``; ``z`` is its face nearest to the camera."""
    width = float(rng.uniform(1.7, 2.0))
    length = float(rng.uniform(3.8, 4.8))
    height = float(rng.uniform(1.4, 1.9))
    return Box(
        lo=(x - width / 2, 0.25, z),
        hi=(x + width / 2, height, z + length),
        albedo=float(rng.uniform(0.25, 0.75)),
        contrast=float(rng.uniform(0.25, 0.4)),
        texture_id=int(rng.integers(1 << 30)),
        velocity=velocity,
    )


def _vehicles(rng: np.random.Generator, speed: float) -> tuple[Box, ...]:
    """Traffic: a near lead car, cars ahead in the right lane, oncoming cars, all ≥ NEAREST."""
    cars: list[Box] = []
    # Same direction: never slower than the rig, so they never come closer than at t = 0.
    lead_speed = speed + float(rng.uniform(0.3, 1.5))
    cars.append(_car(0.0, float(rng.uniform(NEAREST, 5.0)), rng, (0, 0, lead_speed)))
    cars.append(_car(0.0, float(rng.uniform(25.0, 40.0)), rng, (0, 0, lead_speed)))
    right_speed = speed + float(rng.uniform(1.0, 4.0))
    z = float(rng.uniform(7.0, 12.0))
    for _ in range(3):
        cars.append(_car(3.5, z, rng, (0, 0, right_speed)))
        z += float(rng.uniform(12.0, 30.0))
    # Oncoming, in the far lane beyond the median: they pass at 6 m to the left (d ≤ 62 px).
    oncoming = -float(rng.uniform(8.0, 13.0))
    z = float(rng.uniform(60.0, 90.0))
    for _ in range(6):
        cars.append(_car(-6.5, z, rng, (0, 0, oncoming)))
        z += float(rng.uniform(20.0, 50.0))
    return tuple(cars)


@lru_cache(maxsize=256)
def _roadside(seed: int, block: int) -> tuple[Box, ...]:
    """Lay out the static boxes beside the road for ``z`` in ``[50·block, 50·(block + 1))``."""
    rng = np.random.default_rng([seed, 0x51DE, block + 1_000_000])
    z_start = block * _BLOCK
    boxes: list[Box] = []
    for side in (-1.0, 1.0):
        kerb = 8.35 if side < 0 else 5.35
        # Buildings and walls at varied setbacks, with gaps.
        z = z_start + float(rng.uniform(0.0, 6.0))
        while z < z_start + _BLOCK:
            length = float(rng.uniform(6.0, 22.0))
            if rng.random() < 0.25:  # a low wall close to the sidewalk
                near = kerb + float(rng.uniform(0.8, 2.0))
                far, top, period = near + 0.4, float(rng.uniform(1.0, 2.2)), 0.0
            else:
                near = kerb + float(rng.uniform(2.0, 9.0))
                far = near + float(rng.uniform(6.0, 15.0))
                top, period = float(rng.uniform(4.0, 16.0)), float(rng.uniform(0.0, 1.2))
            x0, x1 = (-far, -near) if side < 0 else (near, far)
            boxes.append(
                Box(
                    lo=(x0, 0.0, z),
                    hi=(x1, top, z + length),
                    albedo=float(rng.uniform(0.35, 0.8)),
                    contrast=float(rng.uniform(0.25, 0.4)),
                    texture_scale=float(rng.uniform(1.0, 3.0)),
                    stripe_period=period if period > 0.5 else 0.0,
                    texture_id=int(rng.integers(1 << 30)),
                )
            )
            z += length + float(rng.uniform(1.0, 10.0))
        # Poles at the kerb, and now and then a parked car.
        z = z_start + float(rng.uniform(0.0, 25.0))
        while z < z_start + _BLOCK:
            x = side * (kerb + 0.5)
            boxes.append(
                Box(
                    lo=(x - 0.08, 0.0, z),
                    hi=(x + 0.08, float(rng.uniform(4.0, 8.0)), z + 0.16),
                    albedo=float(rng.uniform(0.3, 0.8)),
                    contrast=0.35,
                    texture_id=int(rng.integers(1 << 30)),
                )
            )
            z += float(rng.uniform(18.0, 35.0))
        if side > 0 and rng.random() < 0.6:
            z = z_start + float(rng.uniform(0.0, _BLOCK - 5.0))
            boxes.append(_car(kerb + 1.1, z, rng, (0.0, 0.0, 0.0)))
    return tuple(boxes)


def driving_world_at(world: World, rig: StereoRig, time: float) -> tuple[World, StereoRig]:
    """Return the driving world and rig at ``time``: traffic, visible roadside, far wall."""
    moved_rig = rig.at(time)
    z = moved_rig.position[2]
    first, last = math.floor((z - _BLOCK) / _BLOCK), math.floor((z + _AHEAD) / _BLOCK)
    roadside = tuple(b for k in range(first, last + 1) for b in _roadside(world.seed, k))
    traffic = tuple(
        b for b in world.at(time).boxes if b.hi[2] > z and b.lo[2] < z + _AHEAD + _BLOCK
    )
    return replace(world, boxes=traffic + roadside, far_wall_z=z + _FAR_WALL), moved_rig


def make_driving_sequence(
    n_frames: int = 60,
    width: int = 620,
    height: int = 188,
    fps: float = 10.0,
    seed: int = 0,
    baseline: float = 0.54,
) -> Iterator[StereoFrame]:
    """Render a KITTI-like drive: the rig moves along a road with traffic and buildings.

    The camera (``f = 721.5·width/1242``, height 1.65 m, ``baseline``) drives at 8–12 m/s;
    frame ``i`` has ``stamp = i / fps``. Frames are rendered lazily and depend only on
    ``seed``, ``i / fps`` and the image size, not on ``n_frames``. The nearest surface is
    ``NEAREST`` metres away: at most ``0.078·width`` px disparity (97 px at 1242 wide). The
    textured backdrop above the horizon has no GT (``inf``), as the sky of a real drive.
    """
    world, rig = driving_setup(width, height, fps, seed, baseline)
    for i in range(n_frames):
        time = i / fps
        world_t, rig_t = driving_world_at(world, rig, time)
        yield render_stereo(world_t, rig_t, stamp=time, noise_seed=[seed, i])
