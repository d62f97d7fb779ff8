"""The ego-motion residual and flicker: exact motion of the synthetic drive, hand cases, masks.

``numpy_residual`` is a plain numpy re-computation written from the definition in
:mod:`dispeval_ros.core.egomotion` (not from its kernels); ``bench/bench_egomotion.py`` times
it against the kernels.
"""

from __future__ import annotations

import math
from dataclasses import replace
from functools import lru_cache

import numpy as np
import pytest
from bag_support import rig_step

from dispeval_ros.core import criteria as crit
from dispeval_ros.core.camera import Camera
from dispeval_ros.core.egomotion import (
    BASE_COLUMNS,
    STATUS_NAMES,
    EgoMotionOptions,
    FlickerWindow,
    MotionFrame,
    PinholeCamera,
    TemporalSums,
    camera_motion,
    egomotion_residual,
    flicker,
    prepare_frame,
)
from dispeval_ros.errors import ConfigurationError, InputError, ShapeMismatchError
from dispeval_ros.testbed import (
    FAR_WALL,
    FIRST_BOX,
    GROUND,
    driving_setup,
    driving_world_at,
    frame_from_views,
    render_pair,
    scene_setup,
)

NO_FIT = EgoMotionOptions(fit_offset=False)


# --------------------------------------------------------------------------------------------
# The plain numpy re-computation


def numpy_residual(
    source: MotionFrame,
    target: MotionFrame,
    motion: np.ndarray,
    camera: PinholeCamera,
    options: EgoMotionOptions,
    offset: float,
    cells: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sums per cell (columns as :data:`BASE_COLUMNS` + bad counts), status and residual maps."""
    height, width = source.shape
    f, fb, doffs = camera.camera.f, camera.camera.fb, camera.camera.doffs
    cx, cy = camera.cx, camera.cy
    rt = np.linalg.inv(motion)[:3]
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    with np.errstate(all="ignore"):
        s = source.disparity.astype(np.float64) - offset + doffs
        z = fb / s
        u, v = (x - cx) / f, (y - cy) / f
        qx = z * (rt[0, 0] * u + (rt[0, 1] * v + rt[0, 2])) + rt[0, 3]
        qy = z * (rt[1, 0] * u + (rt[1, 1] * v + rt[1, 2])) + rt[1, 3]
        qz = z * (rt[2, 0] * u + (rt[2, 1] * v + rt[2, 2])) + rt[2, 3]
        inverse = 1.0 / qz
        xp, yp = cx + f * qx * inverse, cy + f * qy * inverse
        predicted = fb * inverse - doffs
    has_depth = s > 0

    def lands(margin: float) -> np.ndarray:
        return (
            has_depth
            & (qz > 0)
            & (xp >= margin)
            & (xp <= width - 1 - margin)
            & (yp >= margin)
            & (yp <= height - 1 - margin)
        )

    splat = lands(0.0)
    x0 = np.minimum(np.where(splat, xp, 0).astype(np.int64), width - 2)
    y0 = np.minimum(np.where(splat, yp, 0).astype(np.int64), height - 2)
    wx, wy = np.where(splat, xp, 0) - x0, np.where(splat, yp, 0) - y0

    def bilinear(image: np.ndarray) -> np.ndarray:
        a, b = image[y0, x0].astype(np.float64), image[y0, x0 + 1].astype(np.float64)
        c, d = image[y0 + 1, x0].astype(np.float64), image[y0 + 1, x0 + 1].astype(np.float64)
        top = a + wx * (b - a)
        return top + wy * (c + wx * (d - c) - top)

    moving = np.zeros((height, width), bool)
    if source.image.size and target.image.size:
        difference = np.abs(source.image - bilinear(target.image))
        moving = splat & (difference > options.photometric_threshold)
    splat &= ~moving  # a point that moved hides nothing
    zbuffer = np.full((height, width), -np.inf, np.float32)
    for dy in (0, 1):
        for dx in (0, 1):
            np.maximum.at(
                zbuffer, (y0[splat] + dy, x0[splat] + dx), predicted[splat].astype(np.float32)
            )
    kept = lands(options.border)
    x0 = np.minimum(np.where(kept, xp, 0).astype(np.int64), width - 2)
    y0 = np.minimum(np.where(kept, yp, 0).astype(np.int64), height - 2)
    wx, wy = np.where(kept, xp, 0) - x0, np.where(kept, yp, 0) - y0
    with np.errstate(all="ignore"):
        rounded = (np.floor(yp + 0.5).astype(np.int64), np.floor(xp + 0.5).astype(np.int64))
        rounded = (np.clip(rounded[0], 0, height - 1), np.clip(rounded[1], 0, width - 1))
        nearest = zbuffer[rounded].astype(np.float64)
        observed = bilinear(target.disparity) - offset
        hidden = (
            nearest > predicted.astype(np.float32).astype(np.float64) + options.occlusion_tolerance
        )
        no_target = ~(observed + doffs > 0)
        edge = source.edges | target.edges[rounded]
        residual = observed - predicted
        residual_z = fb / (observed + doffs) - qz
    status = np.full((height, width), 0, np.int8)
    rules = ((~has_depth, 1), (~kept, 2), (hidden, 3), (no_target, 4), (edge, 5), (moving, 6))
    decided = np.zeros((height, width), bool)
    for mask, code in rules:
        status[mask & ~decided] = code
        decided |= mask
    counted = status == 0
    residual = np.where(counted, residual, np.nan)
    residual_z = np.where(counted, residual_z, np.nan)
    sums = numpy_cell_sums(status, residual, residual_z, cells, options.thresholds)
    return sums, status, residual


def numpy_cell_sums(
    status: np.ndarray,
    residual: np.ndarray,
    residual_z: np.ndarray,
    cells: np.ndarray | None,
    thresholds: tuple[float, ...],
) -> np.ndarray:
    """Per cell: pixels, each status's count, the counted pixels' terms, the bad counts."""
    cells = np.zeros(status.shape, np.int64) if cells is None else cells
    n_cells = int(cells.max()) + 1
    inside = cells >= 0
    counted = (status == 0) & inside
    columns = [np.bincount(cells[inside], minlength=n_cells)]
    columns += [np.bincount(cells[inside & (status == k)], minlength=n_cells) for k in range(7)]
    c = cells[counted]
    r, rz = residual[counted].astype(np.float64), residual_z[counted].astype(np.float64)
    for values in (np.abs(r), r, r * r, np.abs(rz), rz * rz):
        columns.append(np.bincount(c, weights=values, minlength=n_cells))
    for t in thresholds:
        columns.append(np.bincount(c[np.abs(r) > t], minlength=n_cells))
    return np.stack(columns, axis=1).astype(np.float64)


def numpy_edges(disparity: np.ndarray, gap: float, width: int) -> np.ndarray:
    """Both ends of every 4-neighbour jump > ``gap`` between valid pixels, dilated width × width."""
    with np.errstate(invalid="ignore"):
        across = np.abs(np.diff(disparity, axis=1)) > gap
        down = np.abs(np.diff(disparity, axis=0)) > gap
    jumps = np.zeros(disparity.shape, bool)
    jumps[:, 1:] |= across
    jumps[:, :-1] |= across
    jumps[1:] |= down
    jumps[:-1] |= down
    reach = width // 2
    padded = np.pad(jumps, reach)
    out = np.zeros_like(jumps)
    height, columns = jumps.shape
    for dy in range(width):
        for dx in range(width):
            out |= padded[dy : dy + height, dx : dx + columns]
    return out


def numpy_flicker(
    frames: list[MotionFrame],
    camera: Camera,
    options: EgoMotionOptions,
    cells: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Flicker from its definition: sums per cell (as :func:`numpy_cell_sums`), status, spread.

    Missing where a frame has no estimate; then near an edge of the window's mean map; then
    moving where the left images' range exceeds the photometric threshold; else counted.
    """
    stack = np.stack([frame.disparity for frame in frames]).astype(np.float64)
    missing = ~(stack + camera.doffs > 0).all(axis=0)
    with np.errstate(all="ignore"):
        mean = np.where(missing, np.nan, stack.mean(axis=0)).astype(np.float32)
        spread = np.std(stack, axis=0, ddof=1)
        spread_z = np.std(camera.fb / (stack + camera.doffs), axis=0, ddof=1)
    edge = numpy_edges(mean, options.edge_gap, options.edge_width)
    moving = np.zeros(missing.shape, bool)
    if frames[0].image.size:
        images = np.stack([frame.image for frame in frames]).astype(np.int64)
        moving = images.max(axis=0) - images.min(axis=0) > options.photometric_threshold
    status = np.select([missing, edge, moving], [1, 5, 6], 0).astype(np.int8)
    counted = status == 0
    spread = np.where(counted, spread, np.nan).astype(np.float32)
    spread_z = np.where(counted, spread_z, np.nan).astype(np.float32)
    sums = numpy_cell_sums(status, spread, spread_z, cells, options.thresholds)
    return sums, status, spread


# --------------------------------------------------------------------------------------------
# The synthetic drive: exact disparity and exact motion


@lru_cache(maxsize=4)
def drive_frame(index: int, width: int = 620, height: int = 188):
    """Frame ``index`` of the drive (10 fps), its rig and which left pixels see static things."""
    world, rig = driving_setup(width, height, 10.0, 0)
    world_t, rig_t = driving_world_at(world, rig, index / 10.0)
    left, right = render_pair(world_t, rig_t)
    frame = frame_from_views(left, right, rig_t, stamp=index / 10.0, noise_seed=[0, index])
    static = left.surface == GROUND
    for i, box in enumerate(world_t.boxes):
        if box.velocity == (0.0, 0.0, 0.0):
            static |= left.surface == FIRST_BOX + i
    assert not static[left.surface == FAR_WALL].any()  # it keeps its distance: not static
    return frame, rig_t, static


def drive_motion(first: int, second: int) -> np.ndarray:
    """The pose of the left camera at ``second`` in its frame at ``first``.

    The world is ``x`` right, ``y`` up, ``z`` forward; the camera frame is ``x`` right, ``y``
    down, ``z`` forward, and the rig never turns: the motion is a translation.
    """
    (_, a, _), (_, b, _) = drive_frame(first), drive_frame(second)
    return rig_step(a, b)


def drive_camera() -> PinholeCamera:
    _, rig, _ = drive_frame(0)
    return PinholeCamera(rig.camera, rig.cx, rig.cy)


def drive_pair(
    estimates: tuple[np.ndarray, np.ndarray] | None = None,
    options: EgoMotionOptions | None = None,
    second: int = 1,
) -> TemporalSums:
    (f0, _, _), (f1, _, _) = drive_frame(0), drive_frame(second)
    e0, e1 = estimates or (f0.gt_left, f1.gt_left)
    source = prepare_frame(e0, f0.left, options=options)
    target = prepare_frame(e1, f1.left, options=options)
    return egomotion_residual(
        source, target, drive_motion(0, second), drive_camera(), options=options, keep_maps=True
    )


@pytest.mark.parametrize("second", [1, 2])
def test_true_disparity_of_the_drive_is_below_a_tenth_of_a_pixel(second):
    result = drive_pair(second=second)
    status, residual, _ = result.maps
    static = drive_frame(0)[2]
    seen = (status == 0) & static
    assert seen.sum() > 0.4 * static.sum()
    errors = np.abs(residual[seen])
    assert errors.mean() < 0.01
    assert np.percentile(errors, 99) < 0.1
    assert abs(result.offsets[0]) < 0.01  # the true disparity needs no offset
    summary = result.summary("all")
    assert sum(summary[f"n_{name}"] for name in STATUS_NAMES) == summary["n"]
    assert summary["n"] == static.size


def test_a_noisy_method_scores_higher_than_the_true_disparity():
    rng = np.random.default_rng(5)
    (f0, _, _), (f1, _, _) = drive_frame(0), drive_frame(1)
    noisy = tuple(
        f.gt_left + rng.normal(0, 0.3, f.gt_left.shape).astype(np.float32) for f in (f0, f1)
    )
    true, scored = drive_pair().summary("all"), drive_pair(noisy).summary("all")
    assert scored["rms"] > true["rms"]
    assert scored["bad_0.5"] > true["bad_0.5"] + 10
    static = drive_frame(0)[2]
    errors = [
        np.abs(r.maps[1][(r.maps[0] == 0) & static]).mean()
        for r in (drive_pair(), drive_pair(noisy))
    ]
    assert errors[1] > 0.2 > errors[0]


def test_a_constant_bias_scores_what_the_true_disparity_scores():
    (f0, _, _), (f1, _, _) = drive_frame(0), drive_frame(1)
    biased = (f0.gt_left + np.float32(1), f1.gt_left + np.float32(1))
    true, shifted = drive_pair(), drive_pair(biased)
    assert shifted.offsets[0] == pytest.approx(1.0 + true.offsets[0], abs=1e-3)
    for name in ("mean_abs", "rms", "bad_0.5", "n_residual"):
        assert shifted.summary("all")[name] == pytest.approx(true.summary("all")[name], rel=2e-3)
    # Without the fit the bias does not cancel under forward motion: the depth changes.
    plain = drive_pair(biased, NO_FIT)
    static = drive_frame(0)[2]
    seen = (plain.maps[0] == 0) & static
    assert np.abs(plain.maps[1][seen]).mean() > 0.05
    assert plain.offsets == (0.0,)


def test_a_constant_bias_cancels_exactly_for_a_static_camera():
    (f0, _, _), (f1, _, _) = drive_frame(0), drive_frame(1)
    source, target = prepare_frame(f0.gt_left), prepare_frame(f1.gt_left)
    plus = prepare_frame(f0.gt_left + np.float32(1)), prepare_frame(f1.gt_left + np.float32(1))
    still = np.eye(4)
    a = egomotion_residual(source, target, still, drive_camera(), keep_maps=True)
    b = egomotion_residual(*plus, still, drive_camera(), keep_maps=True)
    assert a.offsets == b.offsets == (0.0,)  # not observable: left at 0
    counted = a.maps[0] == 0
    np.testing.assert_allclose(a.maps[1][counted], (f1.gt_left - f0.gt_left)[counted], atol=1e-6)
    both = counted & (b.maps[0] == 0)  # float32 rounding of d + 1 may move a jump past the gap
    assert both.sum() > 0.999 * counted.sum()
    np.testing.assert_allclose(b.maps[1][both], a.maps[1][both], atol=1e-5)


def test_the_kernels_agree_with_plain_numpy_on_the_drive():
    (f0, _, _), (f1, _, _) = drive_frame(0), drive_frame(2)
    rng = np.random.default_rng(2)
    e0 = f0.gt_left + rng.normal(0, 0.2, f0.gt_left.shape).astype(np.float32)
    e1 = f1.gt_left + rng.normal(0, 0.2, f1.gt_left.shape).astype(np.float32)
    e0[rng.random(e0.shape) < 0.05] = np.nan
    options = EgoMotionOptions(border=3.0)
    source, target = prepare_frame(e0, f0.left), prepare_frame(e1, f1.left)
    texture = crit.texture_set(f0.left, crit.TEXTURE_WINDOW, crit.TEXTURE_THRESHOLD)
    partition = crit.build_partition(np.ones(e0.shape, bool), [texture])
    result = egomotion_residual(
        source, target, drive_motion(0, 2), drive_camera(), partition, options, keep_maps=True
    )
    sums, status, residual = numpy_residual(
        source,
        target,
        drive_motion(0, 2),
        drive_camera(),
        options,
        result.offsets[0],
        partition.cells,
    )
    np.testing.assert_array_equal(result.maps[0], status)
    np.testing.assert_allclose(result.maps[1], residual, rtol=1e-6, atol=1e-6, equal_nan=True)
    # the kernels sum the float32 residual maps: float32 rounding, no more
    np.testing.assert_allclose(result.sums, partition.membership @ sums, rtol=1e-6, atol=1e-6)
    assert set(np.unique(status)) == set(range(7))  # every mask took part


@pytest.mark.parametrize("thresholds", [(0.5,), (0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5)])
def test_any_number_of_thresholds_agrees_with_plain_numpy(thresholds):
    """The row sums count three thresholds in their main pass and the rest three at a time."""
    (f0, _, _), (f1, _, _) = drive_frame(0), drive_frame(1)
    rng = np.random.default_rng(5)
    e0 = f0.gt_left + rng.normal(0, 0.3, f0.gt_left.shape).astype(np.float32)
    e1 = f1.gt_left + rng.normal(0, 0.3, f1.gt_left.shape).astype(np.float32)
    options = EgoMotionOptions(fit_offset=False, thresholds=thresholds)
    source, target = prepare_frame(e0, f0.left), prepare_frame(e1, f1.left)
    result = egomotion_residual(source, target, drive_motion(0, 1), drive_camera(), None, options)
    sums, _, _ = numpy_residual(source, target, drive_motion(0, 1), drive_camera(), options, 0.0)
    assert result.columns[-len(thresholds) :] == tuple(f"bad_{t:g}" for t in thresholds)
    bad = sums[0, len(BASE_COLUMNS) :]
    assert np.all(np.diff(bad) < 0)  # every threshold counts something different
    np.testing.assert_array_equal(result.sums[0, len(BASE_COLUMNS) :], bad)  # counts: exact
    np.testing.assert_allclose(result.sums, sums, rtol=1e-6, atol=1e-6)


# --------------------------------------------------------------------------------------------
# Hand-worked cases

HAND = PinholeCamera(Camera(f=100.0, baseline=0.5), cx=10.0, cy=5.0)  # 21 × 11 px


def forward(metres: float) -> np.ndarray:
    motion = np.eye(4)
    motion[2, 3] = metres
    return motion


def test_a_fronto_parallel_plane_one_metre_closer_by_hand():
    # A wall at 10 m: d = f·B/Z = 50/10 = 5 px; 1 m forward, Z = 9 m: d = 50/9 = 5.5556 px.
    # A pixel at column x lands at 10 + (x − 10)·10/9: inside the 21 columns for |x − 10| ≤ 9,
    # and row y at 5 + (y − 5)·10/9 inside the 11 rows for |y − 5| ≤ 4: 19 × 9 = 171 pixels.
    now = prepare_frame(np.full((11, 21), 5.0))
    later = prepare_frame(np.full((11, 21), 50.0 / 9.0))
    summary = egomotion_residual(now, later, forward(1.0), HAND).summary("all")
    assert (summary["n"], summary["n_residual"], summary["n_border"]) == (231, 171, 60)
    assert summary["mean_abs"] == pytest.approx(0.0, abs=1e-6)
    # An estimate at t + k 0.25 px too large: every counted pixel is 0.25 px off, and in depth
    # 50/(5.5556 + 0.25) − 9 = 8.6124 − 9 = −0.3876 m.
    wrong = prepare_frame(np.full((11, 21), 50.0 / 9.0 + 0.25))
    summary = egomotion_residual(now, wrong, forward(1.0), HAND, options=NO_FIT).summary("all")
    assert summary["mean"] == pytest.approx(0.25, abs=1e-6)
    assert summary["rms"] == pytest.approx(0.25, abs=1e-6)
    assert summary["mean_abs_z"] == pytest.approx(9.0 - 50.0 / (50.0 / 9.0 + 0.25), abs=1e-5)
    assert summary["bad_0.5"] == 0.0
    # The motion the wrong way round (1 m back) is no longer consistent with the estimates.
    back = egomotion_residual(now, later, forward(-1.0), HAND, options=NO_FIT).summary("all")
    assert back["mean_abs"] > 0.5


def plane_disparity(normal, distance, pose: np.ndarray, camera: PinholeCamera, shape) -> np.ndarray:
    """Exact disparity of the plane ``n·P = c`` (frame of the first camera) seen from ``pose``."""
    rotation, translation = pose[:3, :3], pose[:3, 3]
    n = rotation.T @ np.asarray(normal, float)
    c = distance - np.dot(normal, translation)
    y, x = np.mgrid[0 : shape[0], 0 : shape[1]].astype(float)
    rays = np.stack(
        [(x - camera.cx) / camera.camera.f, (y - camera.cy) / camera.camera.f, np.ones(shape)]
    )
    depth = c / np.tensordot(n, rays, axes=1)
    return camera.camera.fb / depth - camera.camera.doffs


def test_a_slanted_plane_under_rotation_and_translation():
    camera = PinholeCamera(Camera(f=300.0, baseline=0.3, doffs=2.0), cx=60.0, cy=40.0)
    shape = (81, 121)
    angle = math.radians(4.0)
    motion = np.eye(4)
    motion[:3, :3] = [
        [math.cos(angle), 0.0, math.sin(angle)],
        [0.0, 1.0, 0.0],
        [-math.sin(angle), 0.0, math.cos(angle)],
    ]
    motion[:3, 3] = (0.3, -0.1, 0.8)
    normal = np.array([0.2, -0.3, 1.0]) / np.linalg.norm([0.2, -0.3, 1.0])
    now = plane_disparity(normal, 6.0, np.eye(4), camera, shape)
    later = plane_disparity(normal, 6.0, motion, camera, shape)
    result = egomotion_residual(prepare_frame(now), prepare_frame(later), motion, camera)
    summary = result.summary("all")
    assert summary["n_residual"] > 0.5 * summary["n"]  # the rest leaves the view
    assert summary["rms"] < 1e-4
    assert abs(result.offsets[0]) < 1e-4
    inverse = np.linalg.inv(motion)  # the other convention (points, not the camera) fails
    wrong = egomotion_residual(
        prepare_frame(now), prepare_frame(later), inverse, camera, options=NO_FIT
    )
    assert wrong.summary("all")["rms"] > 0.1
    biased = egomotion_residual(
        prepare_frame(now + 1.0), prepare_frame(later + 1.0), motion, camera
    )
    assert biased.offsets[0] == pytest.approx(1.0, abs=1e-4)
    assert biased.summary("all")["rms"] < 1e-4


def test_camera_motion_from_two_poses():
    pose_t = np.eye(4)
    pose_t[:3, 3] = (5.0, 0.0, 2.0)
    pose_tk = pose_t.copy()
    pose_tk[:3, 3] = (5.0, 0.0, 3.5)
    np.testing.assert_allclose(camera_motion(pose_t, pose_tk), forward(1.5))


# --------------------------------------------------------------------------------------------
# Masks: each one removes the pixels it is for


@lru_cache(maxsize=1)
def still_scene() -> tuple[MotionFrame, MotionFrame, np.ndarray, PinholeCamera]:
    """The demo scene (nothing moves) seen before and after the rig steps right and forward."""
    world, rig = scene_setup(320, 200)
    moved = replace(rig, position=(rig.position[0] + 0.3, rig.position[1], rig.position[2] + 0.4))
    frames = []
    for seen_from in (rig, moved):
        left, right = render_pair(world, seen_from)
        frame = frame_from_views(left, right, seen_from)
        frames.append(prepare_frame(frame.gt_left, frame.left))
    motion = np.eye(4)
    motion[:3, 3] = (0.3, 0.0, 0.4)
    return frames[0], frames[1], motion, PinholeCamera(rig.camera, rig.cx, rig.cy)


def switched(
    off: EgoMotionOptions, code: int, pair: tuple | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixels a mask removes by default, their residual with it off, and the counted ones'."""
    source, target, motion, camera = pair or still_scene()
    with_mask = egomotion_residual(source, target, motion, camera, options=NO_FIT, keep_maps=True)
    if code == 5:  # edges belong to the prepared frames
        source = replace(source, edges=np.zeros_like(source.edges))
        target = replace(target, edges=np.zeros_like(target.edges))
    without = egomotion_residual(source, target, motion, camera, options=off, keep_maps=True)
    removed = (with_mask.maps[0] == code) & (without.maps[0] == 0)
    counted = with_mask.maps[0] == 0
    return removed, np.abs(without.maps[1][removed]), np.abs(with_mask.maps[1][counted])


def test_the_z_buffer_masks_points_hidden_at_t_plus_k():
    removed, errors, kept = switched(EgoMotionOptions(fit_offset=False, occlusion_tolerance=1e9), 3)
    assert removed.sum() > 100
    assert np.median(errors) > 2.0
    assert np.percentile(kept, 99) < 0.1


def test_the_edge_mask_removes_pixels_near_depth_edges():
    removed, errors, kept = switched(NO_FIT, 5)
    assert removed.sum() > 100
    assert errors.mean() > 0.2 > 20 * kept.mean()


def test_the_photometric_check_masks_moving_traffic():
    (f0, _, _), (f1, _, _) = drive_frame(0), drive_frame(1)
    pair = (
        prepare_frame(f0.gt_left, f0.left),
        prepare_frame(f1.gt_left, f1.left),
        drive_motion(0, 1),
        drive_camera(),
    )
    off = EgoMotionOptions(fit_offset=False, photometric_threshold=1e9)
    removed, errors, kept = switched(off, 6, pair)
    static = drive_frame(0)[2]
    assert removed.sum() > 1000
    assert (removed & ~static).sum() > 5 * (removed & static).sum()
    assert errors.mean() > 10 * kept.mean()
    # Without images there is no photometric check.
    (f0, _, _), (f1, _, _) = drive_frame(0), drive_frame(1)
    blind = egomotion_residual(
        prepare_frame(f0.gt_left), prepare_frame(f1.gt_left), drive_motion(0, 1), drive_camera()
    )
    assert blind.summary("all")["n_moving"] == 0


def test_holes_in_either_map_are_counted_apart():
    now = np.full((11, 21), 5.0)
    now[5, 10] = np.nan  # the centre: it stays in view
    later = np.full((11, 21), 50.0 / 9.0)
    later[2, 3] = 0.0  # missing (≤ 0): the four pixels whose support holds it lose their target
    summary = egomotion_residual(
        prepare_frame(now), prepare_frame(later), forward(1.0), HAND
    ).summary("all")
    assert summary["n_missing"] == 1
    assert summary["n_missing_target"] >= 1
    assert summary["n_residual"] + summary["n_missing_target"] == 170
    margin = EgoMotionOptions(border=2.0)
    bordered = egomotion_residual(
        prepare_frame(now), prepare_frame(later), forward(1.0), HAND, options=margin
    )
    assert bordered.summary("all")["n_border"] > summary["n_border"]


# --------------------------------------------------------------------------------------------
# Flicker of a static camera


def test_flicker_is_the_per_pixel_sample_spread():
    rng = np.random.default_rng(3)
    truth = np.maximum(drive_frame(0)[0].gt_left, 3.0)  # 6 σ above 0: no value becomes ≤ 0
    stack = truth + rng.normal(0, 0.5, (6, *truth.shape)).astype(np.float32)
    stack[2, 10:20, 30:40] = np.nan  # missing in one frame: missing for the window
    camera = drive_camera().camera
    window = FlickerWindow(camera)
    for estimate in stack:
        window.add(prepare_frame(estimate))
    result = window.sums(keep_maps=True)
    status, spread, spread_z = result.maps
    assert (status[10:20, 30:40] == 1).all()
    counted = status == 0
    np.testing.assert_allclose(spread[counted], np.std(stack, axis=0, ddof=1)[counted], rtol=1e-5)
    depth = camera.fb / stack.astype(np.float64)
    np.testing.assert_allclose(spread_z[counted], np.std(depth, axis=0, ddof=1)[counted], rtol=1e-5)
    summary = result.summary("all")
    assert summary["rms"] ** 2 == pytest.approx(0.25, rel=0.05)  # E[s²] = σ²
    biased = flicker([prepare_frame(e + np.float32(1)) for e in stack], camera)
    assert biased.summary("all")["rms"] == pytest.approx(summary["rms"], rel=1e-5)
    still = flicker([prepare_frame(truth)] * 3, camera).summary("all")
    assert still["mean_abs"] == 0.0
    assert still["n_residual"] > 0


@pytest.mark.parametrize("outlier", [0.0, 50.0])
def test_flicker_of_a_long_window_far_from_zero_is_np_std(outlier):
    """Disparities near 5000 px with a spread of 1e-3 px (plain sums of squares lose it all).

    With ``outlier``, the first frame (the sums' shift) is 50 px off the others.
    """
    rng = np.random.default_rng(11)
    base = 5000.0 + rng.random((12, 16)) * 10.0
    stack = (base + rng.normal(0, 1e-3, (40, *base.shape))).astype(np.float32)
    stack[0] += np.float32(outlier)
    camera = Camera(f=1000.0, baseline=0.5)
    window = FlickerWindow(camera, EgoMotionOptions(edge_gap=1e9))
    for estimate in stack:
        window.add(prepare_frame(estimate))
    status, spread, spread_z = window.sums(keep_maps=True).maps
    assert (status == 0).all()
    values = stack.astype(np.float64)
    # the maps are float32: 6e-8 relative, the rest of the error far below
    np.testing.assert_allclose(spread, np.std(values, axis=0, ddof=1), rtol=3e-7)
    np.testing.assert_allclose(spread_z, np.std(camera.fb / values, axis=0, ddof=1), rtol=3e-7)


def test_flicker_masks_edges_and_changing_intensity():
    frame = drive_frame(0)[0]
    images = [frame.left.copy() for _ in range(3)]
    images[1][50:60, 100:120] = 255 - images[1][50:60, 100:120]
    frames = [prepare_frame(frame.gt_left, image) for image in images]
    summary = flicker(frames, drive_camera().camera).summary("all")
    # the mean map's edges (this one's), where a disparity is (the sky has none: missing first)
    scored_edges = frames[0].edges & np.isfinite(frames[0].disparity)
    assert summary["n_edge"] == np.count_nonzero(scored_edges)
    assert summary["n_moving"] > 100
    assert sum(summary[f"n_{name}"] for name in STATUS_NAMES) == summary["n"]


@pytest.mark.parametrize("thresholds", [(0.5, 2.0, 4.0), (0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5)])
def test_flicker_agrees_with_plain_numpy_with_images_and_criteria(thresholds):
    rng = np.random.default_rng(5)
    truth = [drive_frame(0)[0], drive_frame(0)[0], drive_frame(0)[0], drive_frame(0)[0]]
    images = [f.left.copy() for f in truth]
    images[2][40:70, 200:260] = 255 - images[2][40:70, 200:260]  # something passed in front
    estimates = [f.gt_left + rng.normal(0, 0.4, f.gt_left.shape).astype(np.float32) for f in truth]
    estimates[1][100:110, 300:340] = np.nan  # a hole in one frame
    frames = [prepare_frame(e, image) for e, image in zip(estimates, images, strict=True)]
    labels = rng.integers(0, 3, frames[0].shape).astype(np.int32)
    part = crit.CriterionSet("parts", labels, ("a", "b", "c"), np.eye(3, dtype=bool))
    partition = crit.build_partition(rng.random(frames[0].shape) > 0.2, [part])
    options = EgoMotionOptions(thresholds=thresholds)
    window = FlickerWindow(drive_camera().camera, options)
    for frame in frames:
        window.add(frame)
    result = window.sums(partition, keep_maps=True)
    sums, status, spread = numpy_flicker(frames, drive_camera().camera, options, partition.cells)
    np.testing.assert_array_equal(result.maps[0], status)
    np.testing.assert_allclose(result.maps[1], spread, rtol=1e-5, atol=1e-6, equal_nan=True)
    np.testing.assert_allclose(result.sums, partition.membership @ sums, rtol=1e-5, atol=1e-4)
    summary = result.summary("a")
    assert min(summary["n_missing"], summary["n_edge"], summary["n_moving"]) > 0


# --------------------------------------------------------------------------------------------
# Pooling and bad input


def test_pooled_sums_are_exact():
    first, second = drive_pair(), drive_pair(second=2)
    pooled = first + second
    np.testing.assert_array_equal(pooled.sums, first.sums + second.sums)
    assert pooled.offsets == first.offsets + second.offsets
    n = first.column("all", "n_residual") + second.column("all", "n_residual")
    total = first.column("all", "sum_abs") + second.column("all", "sum_abs")
    assert pooled.summary("all")["mean_abs"] == pytest.approx(total / n, rel=1e-12)
    assert pooled.columns == (*BASE_COLUMNS, "bad_0.5", "bad_2", "bad_4")
    with pytest.raises(ConfigurationError, match="cannot pool"):
        _ = first + flicker([prepare_frame(np.ones((188, 620)))] * 2, drive_camera().camera)


@pytest.mark.parametrize(
    ("motion", "words"),
    [
        (np.eye(3), "must be a 4×4 matrix"),
        (np.diag([2.0, 1.0, 1.0, 1.0]), "not a rotation matrix .*rigid"),
        (np.vstack([np.eye(4)[:3], [0.0, 0.0, 1.0, 1.0]]), "last row"),
        (np.full((4, 4), np.nan), "non-finite"),
        ("forward", "not a 4×4 matrix"),
    ],
)
def test_a_bad_motion_is_one_clear_line(motion, words):
    frame = prepare_frame(np.ones((4, 5)))
    with pytest.raises(InputError, match=words):
        egomotion_residual(frame, frame, motion, HAND)


def test_bad_frames_are_refused():
    with pytest.raises(ShapeMismatchError, match="estimate 2 is 6×4 but the first is 5×4"):
        egomotion_residual(
            prepare_frame(np.ones((4, 5))), prepare_frame(np.ones((4, 6))), np.eye(4), HAND
        )
    with pytest.raises(ShapeMismatchError, match="left image is 6×4"):
        prepare_frame(np.ones((4, 5)), np.zeros((4, 6), np.uint8))
    with pytest.raises(InputError, match="8-bit grey image"):
        prepare_frame(np.ones((4, 5)), np.zeros((4, 5), np.float32))
    with pytest.raises(InputError, match="at least 2×2"):
        prepare_frame(np.ones((1, 5)))
    with pytest.raises(InputError, match="at least 2 frames"):
        flicker([prepare_frame(np.ones((4, 5)))], HAND.camera)
    window = FlickerWindow(HAND.camera)
    window.add(prepare_frame(np.ones((4, 5))))
    with pytest.raises(ShapeMismatchError, match="frame 2 of the flicker window"):
        window.add(prepare_frame(np.ones((5, 5))))
    with pytest.raises(ConfigurationError, match="occlusion_tolerance"):
        EgoMotionOptions(occlusion_tolerance=-1.0)


def test_many_cells_and_no_images_agree_with_plain_numpy():
    """The per-pixel path of the row sums (more than four cells) and the z-buffer without images."""
    from dispeval_ros.core.kernels.motion import MASKED_CELLS

    (f0, _, _), (f1, _, _) = drive_frame(0), drive_frame(1)
    rng = np.random.default_rng(7)
    e0 = f0.gt_left + rng.normal(0, 0.3, f0.gt_left.shape).astype(np.float32)
    e1 = f1.gt_left + rng.normal(0, 0.3, f1.gt_left.shape).astype(np.float32)
    classes = MASKED_CELLS + 2
    labels = rng.integers(0, classes, e0.shape).astype(np.int32)
    names = tuple(f"part{i}" for i in range(classes))
    part = crit.CriterionSet("parts", labels, names, np.eye(classes, dtype=bool))
    valid = rng.random(e0.shape) > 0.1  # cells < 0: not evaluated
    partition = crit.build_partition(valid, [part])
    source, target = prepare_frame(e0), prepare_frame(e1)
    result = egomotion_residual(
        source, target, drive_motion(0, 1), drive_camera(), partition, NO_FIT, keep_maps=True
    )
    sums, status, residual = numpy_residual(
        source, target, drive_motion(0, 1), drive_camera(), NO_FIT, 0.0, partition.cells
    )
    np.testing.assert_array_equal(result.maps[0], status)
    np.testing.assert_allclose(result.maps[1], residual, rtol=1e-6, atol=1e-6, equal_nan=True)
    np.testing.assert_allclose(result.sums, partition.membership @ sums, rtol=1e-6, atol=1e-6)
    assert result.summary(names[0])["n_hidden"] > 0
