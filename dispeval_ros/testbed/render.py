"""Ray casting and shading of a :class:`~dispeval_ros.testbed.world.World` into stereo frames.

Every pixel's ray (through the pixel centre, OpenCV convention: pixel ``(x, y)`` is at integer
coordinates) is intersected exactly with every primitive, so the depth ``Z`` and the disparity
``f·B/Z`` are exact for both views: where a surface point is visible in both,
``D_L(x, y) == D_R(x − D_L, y)``. Appearance is a function of the world point alone (textures
are procedural in world coordinates, shading is Lambertian), so the two images agree up to the
seeded sensor noise. Rays that see nothing (sky) or a backdrop (``World.far_wall_backdrop``)
have depth and disparity ``inf``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from dispeval_ros.core.camera import Camera
from dispeval_ros.testbed.world import FAR_WALL, FIRST_BOX, GROUND, NOTHING, StereoRig, Vec3, World

# Face codes of View.face: the outward normal of the surface seen.
FACE_NEG_X, FACE_POS_X, FACE_NEG_Y, FACE_POS_Y, FACE_NEG_Z, FACE_POS_Z = range(6)
_FACE_NORMALS = np.array(
    [(-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)], dtype=np.float64
)

# Procedural texture: value-noise octaves (metres, before a surface's texture_scale).
_LATTICE = 256
_WAVELENGTHS = (0.015, 0.03, 0.06, 0.12, 0.24, 0.48, 0.96)  # ratio 2: a common period
_LIGHT = np.array((-0.35, 0.8, -0.5)) / np.linalg.norm((-0.35, 0.8, -0.5))
_AMBIENT = 0.62
_SKY = 0.82


@dataclass
class View:
    """One rendered camera view: exact depth, what each pixel sees, noiseless radiance.

    ``depth`` is ``Z`` in metres (float64, ``inf`` for sky and a backdrop), ``surface`` the
    surface code
    (``NOTHING``, ``GROUND``, ``FAR_WALL`` or ``FIRST_BOX + i``), ``face`` the face code of the
    outward normal, ``radiance`` the grey level in 0..1 before noise and quantisation.
    """

    depth: np.ndarray
    surface: np.ndarray
    face: np.ndarray
    radiance: np.ndarray


@dataclass
class StereoFrame:
    """A rectified stereo pair with exact ground-truth disparities of both views.

    ``left``/``right`` are uint8 H×W grey images; ``gt_left``/``gt_right`` float32 disparities
    in pixels (``inf`` where the pixel sees nothing); ``stamp`` in seconds.
    """

    left: np.ndarray
    right: np.ndarray
    gt_left: np.ndarray
    gt_right: np.ndarray
    camera: Camera
    stamp: float = 0.0


# --------------------------------------------------------------------------------------------
# Ray casting


def _slab(lo: float, hi: float, origin: float, offsets: np.ndarray, f: float) -> tuple:
    """Entry and exit ray parameters of the slab ``lo ≤ p ≤ hi`` for rays ``p = o + t·off/f``.

    The ray parameter ``t`` is the depth ``Z`` because every ray has unit ``z`` component.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - origin) * f / offsets
        t2 = (hi - origin) * f / offsets
    near = np.minimum(t1, t2)
    far = np.maximum(t1, t2)
    parallel = offsets == 0
    if parallel.any():
        inside = lo <= origin <= hi
        near[parallel] = -math.inf if inside else math.inf
        far[parallel] = math.inf if inside else -math.inf
    return near, far


def _cast(world: World, origin: Vec3, rig: StereoRig) -> tuple[np.ndarray, ...]:
    """Nearest intersection per pixel: depth (float64), surface code and face code."""
    height, width, f = rig.height, rig.width, float(rig.f)
    ox, oy, oz = (float(v) for v in origin)
    du = np.arange(width, dtype=np.float64) - rig.cx  # ray x-slope = du / f
    dv = -(np.arange(height, dtype=np.float64) - rig.cy)  # ray y-slope = dv / f (y up)

    depth = np.full((height, width), np.inf)
    surface = np.full((height, width), NOTHING, dtype=np.int32)
    face = np.full((height, width), FACE_NEG_Z, dtype=np.int8)

    if world.far_wall_z is not None and world.far_wall_z > oz:
        depth[:] = world.far_wall_z - oz
        surface[:] = FAR_WALL

    if oy > 0:  # ground y = 0 below the horizon: Z = f·h / (v − cy)
        below = dv < 0
        t_rows = np.full(height, np.inf)
        t_rows[below] = oy * f / -dv[below]
        hit = t_rows[:, None] < depth
        depth = np.where(hit, t_rows[:, None], depth)
        surface[hit] = GROUND
        face[hit] = FACE_POS_Y

    face_x = np.where(du > 0, FACE_NEG_X, FACE_POS_X).astype(np.int8)
    face_y = np.where(dv > 0, FACE_NEG_Y, FACE_POS_Y).astype(np.int8)
    for index, box in enumerate(world.boxes):
        z_near, z_far = box.lo[2] - oz, box.hi[2] - oz
        if z_far <= 0:
            continue
        x_near, x_far = _slab(box.lo[0], box.hi[0], ox, du, f)
        y_near, y_far = _slab(box.lo[1], box.hi[1], oy, dv, f)
        col_near, col_far = np.maximum(x_near, z_near), np.minimum(x_far, z_far)
        cols = np.flatnonzero((col_near <= col_far) & (col_far > 0))
        rows = np.flatnonzero((y_near <= y_far) & (y_far > 0))
        if cols.size == 0 or rows.size == 0:
            continue
        c0, c1, r0, r1 = cols[0], cols[-1] + 1, rows[0], rows[-1] + 1
        cn, cf = col_near[None, c0:c1], col_far[None, c0:c1]
        yn, yf = y_near[r0:r1, None], y_far[r0:r1, None]
        t_in = np.maximum(cn, yn)
        sub = depth[r0:r1, c0:c1]
        hit = (t_in <= np.minimum(cf, yf)) & (t_in > 0) & (t_in < sub)
        if not hit.any():
            continue
        sub[hit] = t_in[hit]
        surface[r0:r1, c0:c1][hit] = FIRST_BOX + index
        entered = np.where(
            yn >= cn,
            face_y[r0:r1, None],
            np.where(x_near[None, c0:c1] >= z_near, face_x[None, c0:c1], np.int8(FACE_NEG_Z)),
        )
        face[r0:r1, c0:c1][hit] = entered[hit]
    return depth, surface, face


# --------------------------------------------------------------------------------------------
# Appearance


@lru_cache(maxsize=8)
def _lattices(seed: int) -> tuple[np.ndarray, ...]:
    """One random value lattice per texture octave (uniform in [-1, 1]), from the seed."""
    rng = np.random.default_rng([seed, 0x7E57])
    return tuple(
        rng.uniform(-1.0, 1.0, (_LATTICE, _LATTICE)).astype(np.float32) for _ in _WAVELENGTHS
    )


_GROUND_TEXTURE, _FAR_WALL_TEXTURE = -1, -2


def _patch_offsets(seed: int, texture_ids: np.ndarray) -> np.ndarray:
    """Lattice offsets (n × 6 faces × 2) of each texture id: a splitmix64 hash, vectorised."""
    keys = (texture_ids.astype(np.int64).astype(np.uint64)[:, None] * np.uint64(8)) + np.arange(
        6, dtype=np.uint64
    )
    with np.errstate(over="ignore"):
        h = keys ^ (np.uint64(seed & 0xFFFFFFFF) * np.uint64(0x9E3779B97F4A7C15))
        h = (h ^ (h >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        h = (h ^ (h >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        h = h ^ (h >> np.uint64(31))
    low = (h & np.uint64(0xFFFF)).astype(np.float32)
    high = ((h >> np.uint64(16)) & np.uint64(0xFFFF)).astype(np.float32)
    return np.stack([low, high], axis=-1) * np.float32(_LATTICE / 65536.0)


def _surface_table(world: World) -> dict[str, np.ndarray]:
    """Per surface code (shifted by +1, so index 0 is 'nothing'): material properties."""
    boxes = world.boxes
    n = FIRST_BOX + len(boxes) + 1
    albedo = np.full(n, _SKY, dtype=np.float32)
    contrast = np.zeros(n, dtype=np.float32)
    scale = np.ones(n, dtype=np.float32)
    stripes = np.zeros(n, dtype=np.float32)
    origin = np.zeros((n, 3), dtype=np.float64)  # texture coordinates are relative to this
    texture_ids = np.zeros(n, dtype=np.int64)
    albedo[GROUND + 1], contrast[GROUND + 1] = world.ground_albedo, world.ground_contrast
    scale[GROUND + 1] = world.ground_texture_scale
    texture_ids[GROUND + 1] = _GROUND_TEXTURE
    albedo[FAR_WALL + 1], contrast[FAR_WALL + 1] = world.far_wall_albedo, world.far_wall_contrast
    scale[FAR_WALL + 1] = world.far_wall_texture_scale
    texture_ids[FAR_WALL + 1] = _FAR_WALL_TEXTURE
    for i, box in enumerate(boxes):
        k = FIRST_BOX + i + 1
        albedo[k], contrast[k], scale[k] = box.albedo, box.contrast, box.texture_scale
        stripes[k], origin[k], texture_ids[k] = box.stripe_period, box.lo, box.texture_id
    return {
        "albedo": albedo,
        "contrast": contrast,
        "scale": scale,
        "stripes": stripes,
        "origin": origin,
        "offsets": _patch_offsets(world.seed, texture_ids).reshape(n * 6, 2),
    }


def _soft_band(distance: np.ndarray, half_width: float, footprint: np.ndarray) -> np.ndarray:
    """Anti-aliased coverage of a band ``|distance| ≤ half_width`` by a pixel of that footprint."""
    return np.clip(0.5 + (half_width - np.abs(distance)) / footprint, 0.0, 1.0)


def _shade(world: World, origin: Vec3, rig: StereoRig, hits: tuple[np.ndarray, ...]) -> np.ndarray:
    """Radiance (0..1, float32) of every pixel: textured albedo times Lambertian shading."""
    depth, surface, face = hits
    height, width, f = rig.height, rig.width, float(rig.f)
    ox, oy, oz = origin
    table = _surface_table(world)
    code = surface + 1
    seen = code != 0
    t = np.where(seen, depth, 0.0)
    sx = ((np.arange(width) - rig.cx) / f)[None, :]
    sy = (-(np.arange(height) - rig.cy) / f)[:, None]
    X = ox + t * sx  # world coordinates of the surface point (float64)
    Y = oy + t * sy
    Z = oz + t

    # Face-local texture coordinates (s, r) in metres, relative to the surface's origin and
    # reduced modulo the texture's period in float64, so float32 suffices from here on.
    axis = face // 2
    local = table["origin"][code]
    scale = table["scale"][code]
    period = np.float64(_LATTICE * _WAVELENGTHS[-1]) * scale
    s = np.where(axis == 0, Z - local[..., 2], X - local[..., 0])
    r = np.where(axis == 1, Z - local[..., 2], Y - local[..., 1])
    s = np.mod(s, period).astype(np.float32)
    r = np.mod(r, period).astype(np.float32)

    # Pixel footprint on the surface (metres): Z/f stretched by the obliquity of the surface.
    # Horizontal faces (the ground) are stretched along image columns, where both views sample
    # the same rows, so they take the geometric mean of both directions: less blur far away.
    norm = np.sqrt(1.0 + sx * sx + sy * sy)
    slope = np.where(axis == 0, np.abs(sx), np.where(axis == 1, np.sqrt(np.abs(sy) * norm), 1.0))
    cosine = np.maximum(slope / norm, 0.05)
    footprint = np.maximum(t * norm / (f * cosine), 1e-6).astype(np.float32)

    inv_scale = np.float32(1.0) / scale
    rel_footprint = footprint * inv_scale
    off = table["offsets"][code * 6 + face]
    total = np.zeros((height, width), dtype=np.float32)
    weights = np.zeros((height, width), dtype=np.float32)
    for k, (wavelength, lattice) in enumerate(
        zip(_WAVELENGTHS, _lattices(world.seed), strict=True)
    ):
        freq = inv_scale * np.float32(1.0 / wavelength)
        u = np.mod(s * freq + off[..., 0] + np.float32(17 * k), _LATTICE, dtype=np.float32)
        v = np.mod(r * freq + off[..., 1] + np.float32(31 * k), _LATTICE, dtype=np.float32)
        noise = cv2.remap(lattice, u, v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
        # Fade an octave out as it approaches the Nyquist limit of the pixel grid.
        weight = np.clip((np.float32(wavelength) / rel_footprint - 2.0) * 0.5, 0.0, 1.0)
        total += weight * noise
        weights += weight * weight
    texture = total / np.sqrt(np.maximum(weights, np.float32(0.25))) * np.float32(2.2)

    stripe_period = table["stripes"][code]
    striped = stripe_period > 0
    if striped.any():
        stripe = np.where(striped, stripe_period, np.float32(1.0))
        wave = np.sin(s * np.float32(2 * np.pi) / stripe + np.float32(0.7) * texture)
        sharp = np.clip(wave * stripe / (np.float32(2 * np.pi) * footprint), -1.0, 1.0)
        fade = np.clip((stripe / footprint - 4.0) * 0.25, 0.0, 1.0) * (axis != 1)
        texture = np.where(striped, 0.6 * texture + 0.9 * sharp * fade, texture)

    albedo = table["albedo"][code]
    ground = code == GROUND + 1
    for x_lo, x_hi, band_albedo in world.ground_bands:
        inside = ground & (x_lo <= X) & (x_hi > X)
        albedo = np.where(inside, np.float32(band_albedo), albedo)
    intensity = albedo + table["contrast"][code] * texture * np.float32(0.5)
    if world.lane_lines:
        Xg, Zg = X.astype(np.float32), Z.astype(np.float32)
        for line in world.lane_lines:
            cover = _soft_band(Xg - np.float32(line.x), line.width / 2, footprint)
            if line.period > 0:
                phase = np.mod(Zg, np.float32(line.period)) - np.float32(line.dash / 2)
                cover = cover * _soft_band(phase, line.dash / 2, footprint)
            paint = np.float32(0.88) + np.float32(0.05) * texture
            intensity = np.where(ground, intensity + cover * (paint - intensity), intensity)

    lambert = np.clip(_FACE_NORMALS @ _LIGHT, 0.0, None)
    shade = (_AMBIENT + (1.0 - _AMBIENT) * lambert).astype(np.float32)[face]
    radiance = np.where(seen, intensity * shade, np.float32(_SKY))
    return np.clip(radiance, 0.0, 1.0).astype(np.float32)


def render_view(world: World, origin: Vec3, rig: StereoRig) -> View:
    """Ray-cast one camera of ``rig`` placed at ``origin`` (its intrinsics, any position).

    A box that contains the camera is not seen (rays leave it through its inside faces). A
    backdrop is shaded at its distance, then its depth is unknown (``inf``), as sky's is.
    """
    depth, surface, face = _cast(world, origin, rig)
    radiance = _shade(world, origin, rig, (depth, surface, face))
    if world.far_wall_backdrop:
        depth = np.where(surface == FAR_WALL, np.inf, depth)
    return View(depth=depth, surface=surface, face=face, radiance=radiance)


def render_pair(world: World, rig: StereoRig) -> tuple[View, View]:
    """Render the left and right views of ``rig`` (at its current position)."""
    return render_view(world, rig.position, rig), render_view(world, rig.right_position, rig)


def _disparity(depth: np.ndarray, fb: float) -> np.ndarray:
    with np.errstate(divide="ignore"):
        disparity = np.where(np.isfinite(depth), fb / depth, np.inf)
    return disparity.astype(np.float32)


def _expose(radiance: np.ndarray, noise_sigma: float, rng: np.random.Generator) -> np.ndarray:
    grey = radiance * np.float32(255.0)
    if noise_sigma > 0:
        grey = grey + rng.standard_normal(radiance.shape, dtype=np.float32) * noise_sigma
    return np.clip(np.rint(grey), 0, 255).astype(np.uint8)


def frame_from_views(
    left: View,
    right: View,
    rig: StereoRig,
    *,
    stamp: float = 0.0,
    noise_sigma: float = 1.5,
    noise_seed: int | Sequence[int] = 0,
) -> StereoFrame:
    """Quantise two views into a :class:`StereoFrame` with seeded Gaussian sensor noise."""
    rng_left, rng_right = (
        np.random.default_rng(s) for s in np.random.SeedSequence(noise_seed).spawn(2)
    )
    fb = float(rig.f) * float(rig.baseline)
    return StereoFrame(
        left=_expose(left.radiance, noise_sigma, rng_left),
        right=_expose(right.radiance, noise_sigma, rng_right),
        gt_left=_disparity(left.depth, fb),
        gt_right=_disparity(right.depth, fb),
        camera=rig.camera,
        stamp=float(stamp),
    )


def render_stereo(
    world: World,
    rig: StereoRig,
    *,
    stamp: float = 0.0,
    noise_sigma: float = 1.5,
    noise_seed: int | Sequence[int] = 0,
) -> StereoFrame:
    """Render ``world`` through ``rig`` into a :class:`StereoFrame` (images and exact GT)."""
    left, right = render_pair(world, rig)
    return frame_from_views(
        left, right, rig, stamp=stamp, noise_sigma=noise_sigma, noise_seed=noise_seed
    )
