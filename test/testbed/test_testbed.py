"""The synthetic stereo test-bed: exact ground truth, consistent views, working OpenCV methods."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest

from dispeval_ros.errors import ConfigurationError, InputError, ShapeMismatchError
from dispeval_ros.testbed import (
    FAR_WALL,
    FIRST_BOX,
    GROUND,
    NOTHING,
    Box,
    StereoFrame,
    StereoMethod,
    StereoRig,
    World,
    default_methods,
    default_num_disparities,
    driving_setup,
    driving_world_at,
    make_driving_sequence,
    make_scene,
    render_pair,
    render_stereo,
    scene_setup,
)
from dispeval_ros.testbed.lidar import LidarModel, simulate_scan
from dispeval_ros.testbed.scene import FACE_NEG_X, FACE_NEG_Y, FACE_POS_X, NEAREST


@pytest.fixture(scope="module")
def scene() -> StereoFrame:
    return make_scene()


@pytest.fixture(scope="module")
def views():
    world, rig = scene_setup()
    return rig, *render_pair(world, rig)


@pytest.fixture(scope="module")
def estimates(scene: StereoFrame) -> dict[str, np.ndarray]:
    width = scene.left.shape[1]
    return {m.name: m.compute(scene.left, scene.right) for m in default_methods(width)}


@pytest.fixture(scope="module")
def drive() -> list[StereoFrame]:
    return list(make_driving_sequence(n_frames=4, seed=3))


def _frames_equal(a: StereoFrame, b: StereoFrame) -> bool:
    return all(
        np.array_equal(getattr(a, name), getattr(b, name))
        for name in ("left", "right", "gt_left", "gt_right")
    ) and (a.camera, a.stamp) == (b.camera, b.stamp)


# ---------------------------------------------------------------------------------------------
# The scene


def test_make_scene_shapes_types_and_camera(scene: StereoFrame) -> None:
    for image in (scene.left, scene.right):
        assert image.shape == (400, 640)
        assert image.dtype == np.uint8
    for gt in (scene.gt_left, scene.gt_right):
        assert gt.shape == (400, 640)
        assert gt.dtype == np.float32
    assert scene.camera.f == pytest.approx(0.9 * 640)
    assert scene.camera.baseline == pytest.approx(0.12)
    assert scene.camera.doffs == 0.0
    assert scene.stamp == 0.0


def test_make_scene_is_deterministic_per_seed(scene: StereoFrame) -> None:
    assert _frames_equal(scene, make_scene())
    other = make_scene(seed=1)
    assert not np.array_equal(scene.left, other.left)
    assert not np.array_equal(scene.gt_left, other.gt_left)


def test_gt_covers_the_image_and_fits_the_disparity_range(scene: StereoFrame) -> None:
    for gt in (scene.gt_left, scene.gt_right):
        assert np.isfinite(gt).all()
        assert (gt > 0).all()
        assert gt.max() < default_num_disparities(640) <= 128
    # Depths from 1.5 m to the wall at 30 m.
    fb = scene.camera.fb
    assert fb / scene.gt_left.max() == pytest.approx(1.5, abs=0.01)
    assert fb / scene.gt_left.min() == pytest.approx(30.0, abs=0.01)


def test_images_are_textured(scene: StereoFrame) -> None:
    assert scene.left.std() > 20
    assert scene.right.std() > 20
    # Texture at the scale block matchers see, not just large shading differences.
    local = np.abs(np.diff(scene.left.astype(np.int16), axis=1))
    assert np.median(local) >= 3


def test_ground_disparity_matches_hand_computation(scene: StereoFrame, views) -> None:
    rig, left, _right = views
    f, baseline, h, cy = rig.f, rig.baseline, rig.position[1], rig.cy
    assert (f, baseline, h, cy) == (576.0, 0.12, 1.1, 199.5)
    # Pixel (x=300, y=380) sees the road in front of the camera: Z = f·h / (y − cy).
    x, y = 300, 380
    assert left.surface[y, x] == GROUND
    z = 576.0 * 1.1 / (380 - 199.5)
    assert scene.gt_left[y, x] == pytest.approx(576.0 * 0.12 / z, abs=1e-4)
    assert scene.gt_left[y, x] == pytest.approx(19.6909, abs=1e-4)
    # Every ground pixel, both views: d = B·(y − cy)/h, independent of x.
    rows = np.arange(scene.gt_left.shape[0], dtype=np.float64)[:, None]
    expected = np.broadcast_to(baseline * (rows - cy) / h, scene.gt_left.shape)
    for view, gt in ((left, scene.gt_left), (_right, scene.gt_right)):
        ground = view.surface == GROUND
        assert ground.sum() > 10_000
        np.testing.assert_allclose(gt[ground], expected[ground], rtol=1e-6)


def test_far_wall_disparity_is_exact(scene: StereoFrame, views) -> None:
    _rig, left, _right = views
    wall = left.surface == FAR_WALL
    assert wall.any()
    np.testing.assert_allclose(scene.gt_left[wall], scene.camera.fb / 30.0, rtol=1e-6)


def test_left_and_right_gt_agree_where_the_same_surface_is_seen(scene: StereoFrame, views) -> None:
    _rig, left, right = views
    height, width = scene.gt_left.shape
    rng = np.random.default_rng(7)
    ys = rng.integers(0, height, 20_000)
    xs = rng.integers(0, width, 20_000)
    d = scene.gt_left[ys, xs].astype(np.float64)
    xr = xs - d
    # Rounded target, on surfaces whose disparity is constant along a row (all but x-faces).
    xi = np.rint(xr).astype(int)
    inside = (xi >= 0) & (xi < width)
    ys_in, xs_in, xi_in = ys[inside], xs[inside], xi[inside]
    same = (left.surface[ys_in, xs_in] == right.surface[ys_in, xi_in]) & (
        left.face[ys_in, xs_in] == right.face[ys_in, xi_in]
    )
    flat = ~np.isin(left.face[ys_in, xs_in], (FACE_NEG_X, FACE_POS_X))
    keep = same & flat
    assert keep.sum() > 10_000
    np.testing.assert_allclose(
        scene.gt_right[ys_in[keep], xi_in[keep]], scene.gt_left[ys_in[keep], xs_in[keep]], atol=1e-3
    )
    # Any plane: disparity is affine along a row, so interpolating the right GT at x − d is exact.
    x0 = np.floor(xr).astype(int)
    inside = (x0 >= 0) & (x0 + 1 < width)
    ys2, xs2, x0, frac = ys[inside], xs[inside], x0[inside], (xr - np.floor(xr))[inside]
    code = left.surface[ys2, xs2], left.face[ys2, xs2]
    same = np.ones(ys2.shape, dtype=bool)
    for x_right in (x0, x0 + 1):
        same &= (right.surface[ys2, x_right] == code[0]) & (right.face[ys2, x_right] == code[1])
    slanted = same & np.isin(code[1], (FACE_NEG_X, FACE_POS_X))
    assert slanted.sum() > 100
    interpolated = (1 - frac) * scene.gt_right[ys2, x0] + frac * scene.gt_right[ys2, x0 + 1]
    np.testing.assert_allclose(interpolated[same], scene.gt_left[ys2, xs2][same], atol=1e-3)


def test_scene_has_occlusions(scene: StereoFrame) -> None:
    width = scene.gt_left.shape[1]
    xs = np.arange(width)[None, :] - scene.gt_left
    xi = np.rint(xs).astype(int)
    inside = (xi >= 0) & (xi < width)
    target = np.take_along_axis(scene.gt_right, np.clip(xi, 0, width - 1), axis=1)
    occluded = inside & (target > scene.gt_left + 1.0)
    assert occluded.sum() > 1_000
    assert (~inside).sum() > 1_000  # points leaving the right image at the left border


def test_world_without_far_wall_has_sky_with_infinite_gt() -> None:
    rig = StereoRig(width=64, height=48, f=60.0, cx=31.5, cy=23.5, baseline=0.1)
    world = World(boxes=(Box((-1.0, 0.0, 5.0), (1.0, 1.0, 6.0), texture_id=3),))
    frame = render_stereo(world, rig)
    left, _ = render_pair(world, rig)
    sky = left.surface == NOTHING
    assert sky[0].all()  # above the horizon and the box
    assert np.isinf(frame.gt_left[sky]).all()
    assert np.isfinite(frame.gt_left[~sky]).all()
    assert (frame.gt_left[~sky] > 0).all()


def test_backdrop_is_seen_in_the_images_but_has_no_gt() -> None:
    rig = StereoRig(width=64, height=48, f=60.0, cx=31.5, cy=23.5, baseline=0.1)
    wall = World(boxes=(Box((-1.0, 0.0, 5.0), (1.0, 1.0, 6.0), texture_id=3),), far_wall_z=80.0)
    backdrop = replace(wall, far_wall_backdrop=True)
    frame, painted = render_stereo(wall, rig), render_stereo(backdrop, rig)
    # The same images (matchers see the same texture), the same GT off the backdrop.
    assert np.array_equal(frame.left, painted.left)
    assert np.array_equal(frame.right, painted.right)
    for view, real, gt in zip(
        render_pair(backdrop, rig),
        (frame.gt_left, frame.gt_right),
        (painted.gt_left, painted.gt_right),
        strict=True,
    ):
        seen = view.surface == FAR_WALL
        assert seen[0].all()
        assert np.isinf(view.depth[seen]).all()
        assert np.isinf(gt[seen]).all()
        np.testing.assert_allclose(real[seen], rig.camera.fb / 80.0, rtol=1e-6)
        assert np.array_equal(gt[~seen], real[~seen])
        assert np.isfinite(gt[~seen]).all()


def test_driving_backdrop_has_no_gt_and_no_lidar_return(drive: list[StereoFrame]) -> None:
    world, rig = driving_setup(seed=3)
    world_t, rig_t = driving_world_at(world, rig, 0.0)
    assert world_t.far_wall_backdrop
    left, _ = render_pair(world_t, rig_t)
    backdrop = left.surface == FAR_WALL
    assert backdrop.mean() > 0.05  # the sky's share of a KITTI frame
    assert np.isinf(drive[0].gt_left[backdrop]).all()
    assert np.isfinite(drive[0].gt_left[~backdrop]).all()
    assert drive[0].left[backdrop].std() > 5  # still textured for the matchers
    # Even a LiDAR that reaches beyond the backdrop gets no return from it.
    far = LidarModel(max_range=10_000.0)
    assert np.linalg.norm(simulate_scan(world_t, rig_t, far), axis=1).max() < 400.0
    wall = simulate_scan(replace(world_t, far_wall_backdrop=False), rig_t, far)
    assert np.linalg.norm(wall, axis=1).max() > 400.0


def test_box_above_the_camera_is_seen_through_its_underside() -> None:
    rig = StereoRig(width=64, height=48, f=60.0, cx=31.5, cy=23.5, baseline=0.1)
    bridge = Box((-20.0, 3.0, -5.0), (20.0, 4.0, 10.0))  # spans over the camera at 1.2 m
    left, right = render_pair(World(boxes=(bridge,), far_wall_z=50.0), rig)
    for view in (left, right):
        assert (view.surface[0] == FIRST_BOX).all()
        assert (view.face[0] == FACE_NEG_Y).all()
        # The underside y = 3 seen from row 0: Z = f·(3 − 1.2)/cy.
        np.testing.assert_allclose(view.depth[0], 60.0 * 1.8 / 23.5, rtol=1e-12)
    # A box containing the camera is not seen.
    inside = World(boxes=(Box((-1.0, 0.0, -1.0), (1.0, 2.0, 1.0)),), far_wall_z=50.0)
    assert set(np.unique(render_pair(inside, rig)[0].surface)) == {GROUND, FAR_WALL}


def test_box_is_rejected_with_inverted_corners() -> None:
    with pytest.raises(ValueError, match="lo < hi"):
        Box((0.0, 0.0, 2.0), (1.0, 1.0, 1.0))


# ---------------------------------------------------------------------------------------------
# The OpenCV methods


def test_default_methods_are_distinct_configurations() -> None:
    methods = default_methods(640)
    names = [m.name for m in methods]
    assert len(methods) >= 4
    assert len(set(names)) == len(names)
    assert {"bm_fast", "bm_smooth", "sgbm", "sgbm_3way"} <= set(names)
    assert len(set(methods)) == len(methods)
    for method in methods:
        assert method.num_disparities % 16 == 0
        assert method.num_disparities == default_num_disparities(640) == 64
    assert default_num_disparities(1242) == 128
    by_name = {m.name: m for m in methods}
    assert by_name["sgbm"].penalties == (8 * 25, 32 * 25)
    assert by_name["bm_fast"].block_size == 9
    assert by_name["bm_smooth"].block_size == 21


def test_methods_return_ros_style_float_disparities(
    scene: StereoFrame, estimates: dict[str, np.ndarray]
) -> None:
    for method in default_methods(640):
        estimate = estimates[method.name]
        assert estimate.dtype == np.float32
        assert estimate.shape == scene.left.shape
        invalid = estimate < method.min_disparity
        assert (estimate[invalid] == method.min_disparity - 1).all()
        assert invalid.any()  # at least the left border, where no match can exist
        assert estimate[~invalid].max() <= method.max_disparity
        raw = method.compute_raw(scene.left, scene.right)
        np.testing.assert_array_equal(estimate[~invalid], raw[~invalid] / 16.0)


def test_methods_work_on_the_scene(scene: StereoFrame, estimates: dict[str, np.ndarray]) -> None:
    for name, estimate in estimates.items():
        valid = estimate >= 0
        error = np.abs(estimate[valid] - scene.gt_left[valid])
        assert valid.mean() > 0.6, name
        assert error.mean() < 3.0, name
        assert (error > 3).mean() < 0.1, name


def test_methods_differ_from_one_another(estimates: dict[str, np.ndarray]) -> None:
    for (a, ea), (b, eb) in itertools.combinations(estimates.items(), 2):
        assert (ea != eb).mean() > 0.05, (a, b)


def test_matcher_is_created_once_per_method(scene: StereoFrame) -> None:
    method = default_methods(640)[0]
    assert method.matcher() is method.matcher()
    assert method.matcher() is not default_methods(640)[2].matcher()


def test_min_disparity_shifts_the_invalid_value(scene: StereoFrame) -> None:
    method = StereoMethod("bm_shifted", "bm", 64, 9, min_disparity=-8)
    estimate = method.compute(scene.left, scene.right)
    assert method.invalid_value == -9.0
    invalid = estimate < -8
    assert invalid.any()
    assert (estimate[invalid] == -9.0).all()


def test_method_configuration_and_input_errors(scene: StereoFrame) -> None:
    with pytest.raises(ConfigurationError, match="multiple of 16"):
        StereoMethod("x", "bm", 60, 9)
    with pytest.raises(ConfigurationError, match="odd"):
        StereoMethod("x", "sgbm", 64, 4)
    with pytest.raises(ConfigurationError, match="p2 > p1"):
        StereoMethod("x", "sgbm", 64, 5, p1=100, p2=50)
    with pytest.raises(ConfigurationError, match="kind"):
        StereoMethod("x", "census", 64, 5)  # type: ignore[arg-type]
    method = default_methods(640)[0]
    with pytest.raises(ShapeMismatchError):
        method.compute(scene.left, scene.right[:, :-1])
    with pytest.raises(InputError, match="uint8"):
        method.compute(scene.left.astype(np.float32), scene.right)


# ---------------------------------------------------------------------------------------------
# The driving sequence


def test_driving_sequence_stamps_and_camera(drive: list[StereoFrame]) -> None:
    assert len(drive) == 4
    assert [frame.stamp for frame in drive] == pytest.approx([0.0, 0.1, 0.2, 0.3])
    assert np.diff([frame.stamp for frame in drive]) == pytest.approx([0.1] * 3)
    camera = drive[0].camera
    assert camera.f == pytest.approx(721.5377 * 620 / 1242)
    assert camera.baseline == 0.54
    for frame in drive:
        assert frame.left.shape == frame.right.shape == frame.gt_left.shape == (188, 620)
        assert frame.left.dtype == np.uint8
        assert frame.gt_left.dtype == np.float32
        assert frame.left.std() > 20


def test_driving_frames_differ_and_stay_in_range(drive: list[StereoFrame]) -> None:
    limit = default_num_disparities(620)
    for frame in drive:
        for gt in (frame.gt_left, frame.gt_right):
            known = gt[np.isfinite(gt)]  # all but the backdrop (inf: no GT, as the sky)
            assert 0.5 * gt.size < known.size < gt.size
            assert known.min() > 0
            assert known.max() < limit
            assert known.max() <= frame.camera.fb / NEAREST + 1e-3
        near = frame.gt_left[np.isfinite(frame.gt_left)].max()
        assert near > 0.8 * frame.camera.fb / NEAREST  # something near
    for a, b in itertools.pairwise(drive):
        assert (a.left != b.left).mean() > 0.5
        assert (a.gt_left != b.gt_left).mean() > 0.05  # the road itself looks the same


def test_driving_sequence_is_deterministic_and_prefix_stable(drive: list[StereoFrame]) -> None:
    again = list(make_driving_sequence(n_frames=2, seed=3))
    assert _frames_equal(again[0], drive[0])
    assert _frames_equal(again[1], drive[1])
    other = next(iter(make_driving_sequence(n_frames=1, seed=4)))
    assert not np.array_equal(other.left, drive[0].left)


def test_driving_sequence_methods_cover_the_range(drive: list[StereoFrame]) -> None:
    frame = drive[0]
    method = default_methods(620)[2]
    estimate = method.compute(frame.left, frame.right)
    valid = (estimate >= 0) & np.isfinite(frame.gt_left)
    assert valid.mean() > 0.55
    assert np.abs(estimate[valid] - frame.gt_left[valid]).mean() < 3.0
    # At KITTI size the nearest surface reaches ~100 px, still below numDisparities = 128.
    f_kitti = 721.5377
    assert 90 < f_kitti * 0.54 / NEAREST < default_num_disparities(1242)
    assert math.isclose(frame.camera.fb / NEAREST, f_kitti * 0.54 / NEAREST * 620 / 1242)
