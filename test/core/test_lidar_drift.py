"""LiDAR drift between scans, worked by hand on a fronto-parallel wall.

The wall is ``Z0 = 10 m`` in front of a camera with ``f = 50 px``, ``B = 0.5 m``
(``d = f·B/Z0 = 2.5 px``) and the principal point at a pixel centre; the camera drives
``Z0/2`` toward it, so every point lands at ``p' = c + 2·(p − c)`` (a pixel centre: the
bilinear read is the pixel itself) with the expected disparity ``2·d = 5 px``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.egomotion import PinholeCamera
from dispeval_ros.core.evaluator import Evaluator
from dispeval_ros.core.lidar_drift import (
    STATUS_NAMES,
    DriftOptions,
    coded_estimate,
    lidar_drift,
)
from dispeval_ros.core.projection import CloudFilter
from dispeval_ros.errors import ConfigurationError, ShapeMismatchError

F, B, Z0 = 50.0, 0.5, 10.0
D0 = F * B / Z0  # 2.5 px at t
D1 = F * B / (Z0 / 2)  # 5 px at t + k


def wall(height: int = 61, width: int = 81) -> tuple[PinholeCamera, np.ndarray, np.ndarray]:
    """The camera (principal point at the centre pixel), the motion, the scan at t."""
    camera = PinholeCamera(Camera(F, B), (width - 1) / 2, (height - 1) / 2)
    motion = np.eye(4)
    motion[2, 3] = Z0 / 2  # the camera at t + k, 5 m forward, in the camera at t
    return camera, motion, np.full((height, width), D0, np.float32)


def drift(
    scans: tuple[np.ndarray, np.ndarray],
    estimates: tuple[np.ndarray, np.ndarray],
    motion: np.ndarray,
    camera: PinholeCamera,
    missing: str = "interpolate",
    **kwargs: object,
):
    options = DriftOptions(missing=missing, **kwargs)  # type: ignore[arg-type]
    coded = [coded_estimate(e, missing) for e in estimates]
    return lidar_drift(*scans, *coded, motion, camera, options=options, keep_maps=True)


def inside(height: int = 61, width: int = 81) -> np.ndarray:
    """The points whose landing ``c + 2·(p − c)`` is inside the image, worked out by hand."""
    rows, columns = np.mgrid[0:height, 0:width]
    cy, cx = (height - 1) / 2, (width - 1) / 2
    return (abs(rows - cy) <= cy / 2) & (abs(columns - cx) <= cx / 2)


def test_exact_maps_drift_zero_and_the_expected_disparity_is_f_b_over_the_new_depth() -> None:
    camera, motion, scan = wall()
    target_scan = np.full(scan.shape, D1, np.float32)
    sums = drift((scan, target_scan), (scan, target_scan), motion, camera)
    one = sums.summary("all")
    assert (one["n"], one["n_drift"]) == (61 * 81, 31 * 41)  # rows 15–45, columns 20–60
    assert one["n_outside"] == 61 * 81 - 31 * 41
    assert one["mean"] == one["rms"] == one["bias_drift"] == 0.0
    np.testing.assert_array_equal(sums.maps[0] == 0, inside())
    # an estimate 0.5 px above 5 px at t + k is 0.5 px of drift at every counted point (exact
    # in binary): not bad_0.5, which counts |c| > 0.5 as every bad-X does
    sums = drift((scan, target_scan), (scan, target_scan + 0.5), motion, camera)
    one = sums.summary("all")
    assert one["mean"] == one["bias_drift"] == 0.5
    assert one["bad_0.5"] == 0.0
    np.testing.assert_array_equal(sums.maps[1][inside()], 0.5)
    sums = drift((scan, target_scan), (scan, target_scan + 0.75), motion, camera)
    assert sums.summary("all")["bad_0.5"] == 100.0


def test_a_landing_between_the_last_column_and_the_edge_is_outside() -> None:
    """Moved half a pixel right (the camera 0.1 m left): the last column lands at W − 0.5,
    where the bilinear support would leave the image."""
    camera, motion, scan = wall()
    motion[:3, 3] = (-0.5 * Z0 / F, 0.0, 0.0)
    sums = drift((scan, scan), (scan, scan), motion, camera)
    one = sums.summary("all")
    assert (one["n_drift"], one["n_outside"]) == (61 * 80, 61)
    np.testing.assert_array_equal(sums.maps[0][:, -1], STATUS_NAMES.index("outside"))
    assert one["mean"] == 0.0


@pytest.mark.parametrize("bias", [1.0, -0.7])
def test_a_constant_bias_drifts_zero_and_shows_in_the_mean_error(bias: float) -> None:
    camera, motion, scan = wall()
    target_scan = np.full(scan.shape, D1, np.float32)
    one = drift((scan, target_scan), (scan + bias, target_scan + bias), motion, camera).summary(
        "all"
    )
    assert one["n_drift"] == 31 * 41
    assert one["mean"] == pytest.approx(0.0, abs=1e-6)
    assert one["bias_drift"] == pytest.approx(0.0, abs=1e-6)
    assert one["mean_error"] == pytest.approx(bias, abs=1e-6)


def test_per_frame_noise_drifts_by_its_expected_value() -> None:
    """Independent noise σ at t and t + k: ``c`` is N(0, 2σ²), ``E|c| = 2σ/√π``."""
    height, width, sigma = 601, 801, 0.2
    camera, motion, scan = wall(height, width)
    rng = np.random.default_rng(24)
    noisy = [(value + rng.normal(0, sigma, scan.shape)).astype(np.float32) for value in (D0, D1)]
    one = drift((scan, np.full(scan.shape, D1, np.float32)), tuple(noisy), motion, camera).summary(
        "all"
    )
    assert one["n_drift"] == 301 * 401  # 120 701 points
    assert one["mean"] == pytest.approx(2 * sigma / math.sqrt(math.pi), rel=0.01)
    assert one["rms"] == pytest.approx(math.sqrt(2) * sigma, rel=0.01)
    assert abs(one["bias_drift"]) < 0.01
    assert one["bad_0.5"] == pytest.approx(100 * math.erfc(0.5 / (2 * sigma)), rel=0.05)


def test_each_drop_reason_is_counted_on_the_points_it_applies_to() -> None:
    camera, motion, scan = wall()
    target_scan = np.full(scan.shape, D1, np.float32)
    near = 31, 43  # odd: the landings (even) 3 px away are the window's edge
    target_scan[near] = 1.2 * D1  # a point of scan t + k nearer by 1/1.2 − 1 = −17 %
    target_scan[10, 10] = 1.05 * D1  # nearer by 5 % only: within the 10 % gap, hides nothing
    target_scan[near[0], near[1] - 1] = np.nan  # not a point: the near one still hides
    estimate, target = scan.copy(), np.full(scan.shape, D1, np.float32)
    estimate[20, 30] = np.nan  # a hole at t (lands at (10, 20))
    target[40, 50] = 0  # a hole at t + k: the landing of (35, 45)
    scans = (scan, target_scan)
    sums = drift(scans, (estimate, target), motion, camera, "ignore")
    status = sums.maps[0]
    rows, columns = np.mgrid[0:61, 0:81]
    hidden = inside() & (abs(2 * rows - 30 - near[0]) <= 3) & (abs(2 * columns - 40 - near[1]) <= 3)
    assert hidden.sum() == 4 * 4  # landings within the 7×7 window: rows 29–32, columns 40–43
    np.testing.assert_array_equal(status == STATUS_NAMES.index("hidden"), hidden)
    assert status[20, 30] == STATUS_NAMES.index("missing")
    assert status[35, 45] == STATUS_NAMES.index("missing_target")
    one = sums.summary("all")
    assert (one["n_hidden"], one["n_missing"], one["n_missing_target"]) == (16, 1, 1)
    assert one["n_drift"] == 31 * 41 - 18
    assert one["mean"] == pytest.approx(0.0, abs=1e-6)
    # thesis: the holes are scored as 0 — the hole at t drifts by +d, the one at t + k by −2d
    thesis = drift(scans, (estimate, target), motion, camera, "thesis")
    np.testing.assert_allclose(thesis.maps[1][20, 30], D0, atol=1e-6)
    np.testing.assert_allclose(thesis.maps[1][35, 45], -D1, atol=1e-6)
    assert thesis.summary("all")["n_drift"] == 31 * 41 - 16
    # the visibility test off: nothing hidden
    off = drift(scans, (estimate, target), motion, camera, "ignore", visibility=CloudFilter(0))
    assert off.summary("all")["n_hidden"] == 0


def test_points_behind_the_camera_are_dropped_as_behind() -> None:
    camera, motion, scan = wall()
    scan[:, :40] = F * B / 20.0  # the left half 20 m away; the right half stays at 10 m
    motion[2, 3] = 15.0  # 15 m forward: the 10 m half is behind
    one = drift((scan, scan), (scan, scan), motion, camera).summary("all")
    assert one["n_behind"] == 61 * 41
    assert one["n_behind"] + one["n_outside"] + one["n_drift"] == one["n"]


def test_criteria_come_from_the_scan_at_t_and_pool_exactly() -> None:
    camera, motion, scan = wall()
    scan[:, 30:] = F * B / 40.0  # a far part (40 m) beside the near wall (10 m)
    partition = Evaluator(criteria=("all", "depth"), depth_ranges=[(0, 20), (20, math.inf)])
    reference = partition.reference(scan, camera=camera.camera).partition
    target = scan.copy()
    target[:, :] = np.where(scan > 1, D1, F * B / 35.0)
    coded = [coded_estimate(m, "interpolate") for m in (scan, target + 0.1)]
    one = lidar_drift(scan, target, *coded, motion, camera, reference)
    names = reference.criteria
    assert names[0] == "all"
    assert len(names) == 3
    counts = {c: one.summary(c)["n"] for c in names}
    assert counts["all"] == sum(counts[c] for c in names[1:]) == scan.size
    twice = one + one
    np.testing.assert_array_equal(twice.sums, 2 * one.sums)
    assert twice.summary("all")["mean"] == one.summary("all")["mean"]


def test_bad_input_is_one_clear_error() -> None:
    camera, motion, scan = wall()
    with pytest.raises(ShapeMismatchError, match="the estimate at t \\+ k is 80×61"):
        lidar_drift(scan, scan, scan, scan[:, :80], motion, camera)
    with pytest.raises(ConfigurationError, match="unknown missing-estimate policy 'zero'"):
        DriftOptions(missing="zero")
    base = lidar_drift(scan, scan, scan, scan, motion, camera)
    other = lidar_drift(
        scan, scan, scan, scan, motion, camera, options=DriftOptions(thresholds=(1.0,))
    )
    with pytest.raises(ConfigurationError, match="cannot pool drift sums"):
        _ = base + other


def test_the_estimate_at_t_plus_k_is_read_bilinearly() -> None:
    """Moved half a pixel right and down over a target estimate affine in the image (which a
    bilinear read gives exactly): ``c = 0.01·(x + ½) + 0.02·(y + ½)``."""
    camera, motion, scan = wall()
    motion[:3, 3] = (-0.5 * Z0 / F, -0.5 * Z0 / F, 0.0)
    rows, columns = np.mgrid[0:61, 0:81]
    target = (D0 + 0.01 * columns + 0.02 * rows).astype(np.float32)
    sums = drift((scan, scan), (scan, target), motion, camera)
    status, change = sums.maps
    assert sums.summary("all")["n_drift"] == 60 * 80
    expected = 0.01 * (columns + 0.5) + 0.02 * (rows + 0.5)
    np.testing.assert_allclose(change[status == 0], expected[status == 0], atol=1e-5)
