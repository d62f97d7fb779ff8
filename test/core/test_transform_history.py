"""TransformHistory: /tf over time beside /tf_static, with tf2's lookup semantics.

Expected matrices are written here by hand (rotations about z as cos/sin, the optical mount
as its axes) or from an analytic motion, not with the project's pose helpers.
"""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from dispeval_ros.core.transform_history import (
    ExtrapolationError,
    TransformChainError,
    TransformDataError,
    TransformHistory,
)
from dispeval_ros.core.transforms import StaticTransform, TransformTree, check_rotation
from dispeval_ros.errors import CalibrationError, InputError

MS = 1_000_000
S = 1_000_000_000
# base_link (x forward, y left, z up) → camera optical frame (z forward, x right, y down),
# 1 m ahead and 0.5 m up: the columns are the camera's axes in base_link.
MOUNT = np.array(
    [[0.0, 0.0, 1.0, 1.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.5], [0.0, 0.0, 0.0, 1.0]]
)


def _yaw(angle: float, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1.0]])


def _odom(stamp: int, matrix: np.ndarray) -> tuple[int, StaticTransform]:
    return stamp, StaticTransform("odom", "base_link", matrix)


def _vehicle(samples: list[tuple[int, np.ndarray]]) -> TransformHistory:
    history = TransformHistory()
    history.add_static([StaticTransform("base_link", "camera", MOUNT)])
    for stamp, matrix in samples:
        history.add(*_odom(stamp, matrix))
    return history


def _analytic(t: float) -> np.ndarray:
    """odom → base_link: 2 m/s along odom x plus 1 m/s up, turning at 0.5 rad/s."""
    return _yaw(0.5 * t, 2.0 * t, 0.3, 1.0 * t)


def test_driving_forward_one_metre_is_z_one_in_the_camera() -> None:
    history = _vehicle([(0, np.eye(4)), (S, _yaw(0.0, x=1.0))])
    motion = history.camera_motion("camera", 0, S)
    expected = np.eye(4)
    expected[2, 3] = 1.0
    np.testing.assert_allclose(motion, expected, atol=1e-12)
    # Backwards in time: the inverse.
    np.testing.assert_allclose(history.camera_motion("camera", S, 0)[2, 3], -1.0, atol=1e-12)


def test_a_hand_worked_chain() -> None:
    history = _vehicle([(0, _yaw(math.pi / 2, x=3.0)), (S, _yaw(math.pi / 2, x=3.0))])
    # The camera's origin is 1 m ahead of base_link: base_link faces odom +y after a quarter turn.
    to_odom = history.lookup("odom", "camera", S // 2)
    np.testing.assert_allclose(to_odom @ [0, 0, 0, 1], [3.0, 1.0, 0.5, 1.0], atol=1e-12)
    # 2 m along the optical axis is 2 m further along odom +y; the inverse lookup undoes it.
    np.testing.assert_allclose(to_odom @ [0, 0, 2, 1], [3.0, 3.0, 0.5, 1.0], atol=1e-12)
    back = history.lookup("camera", "odom", S // 2)
    np.testing.assert_allclose(back @ [3.0, 3.0, 0.5, 1.0], [0, 0, 2, 1], atol=1e-12)
    np.testing.assert_allclose(history.lookup("camera", "camera", 5), np.eye(4))
    # A lookup returns a new array: changing it changes nothing stored.
    history.lookup("odom", "base_link", S)[:] = 0
    history.lookup("base_link", "camera", S)[:] = 0
    np.testing.assert_allclose(history.lookup("odom", "camera", S), to_odom, atol=1e-12)
    # A turn in place by +90° about z: the camera turns about its −y axis (y is down).
    turn = _vehicle([(0, np.eye(4)), (S, _yaw(math.pi / 2))]).camera_motion("camera", 0, S)
    # The camera at t1 sits where base_link's x = 1 went: (0, 1, 0.5) in odom, i.e. 1 m to the
    # left (camera −x) and 1 m back (camera −z) of the camera at t0.
    np.testing.assert_allclose(turn[:3, 3], [-1.0, 0.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(turn[:3, :3] @ [0, 0, 1], [-1.0, 0.0, 0.0], atol=1e-12)


def test_interpolation_matches_an_analytic_motion() -> None:
    stamps = [k * 100 * MS for k in range(11)]
    history = _vehicle([(stamp, _analytic(stamp / S)) for stamp in stamps])
    rng = np.random.default_rng(3)
    for stamp in rng.integers(0, S, 40):
        # Slerp is exact for a constant axis at a constant rate; lerp for constant velocity.
        expected = _analytic(int(stamp) / S) @ MOUNT
        np.testing.assert_allclose(
            history.lookup("odom", "camera", int(stamp)), expected, atol=1e-12
        )
    t0, t1 = 123 * MS, 987 * MS
    expected = np.linalg.inv(_analytic(t0 / S) @ MOUNT) @ (_analytic(t1 / S) @ MOUNT)
    np.testing.assert_allclose(history.camera_motion("camera", t0, t1), expected, atol=1e-12)


def test_slerp_takes_the_shorter_arc_across_a_half_turn() -> None:
    # 170° → 190°: the quaternion's w changes sign between the samples.
    history = _vehicle([(0, _yaw(math.radians(170))), (S, _yaw(math.radians(190)))])
    np.testing.assert_allclose(
        history.lookup("odom", "base_link", S // 2), _yaw(math.pi), atol=1e-12
    )


def test_out_of_order_and_repeated_samples() -> None:
    stamps = [k * 50 * MS for k in range(20)]
    ordered = _vehicle([(stamp, _analytic(stamp / S)) for stamp in stamps])
    shuffled_stamps = stamps[:]
    random.Random(5).shuffle(shuffled_stamps)
    shuffled = _vehicle([(stamp, _analytic(stamp / S)) for stamp in shuffled_stamps])
    for stamp in (7 * MS, 333 * MS, 949 * MS):
        np.testing.assert_array_equal(
            shuffled.lookup("odom", "camera", stamp), ordered.lookup("odom", "camera", stamp)
        )
    # A repeated stamp with another value replaces the sample.
    ordered.add(*_odom(100 * MS, _yaw(0.0, x=42.0)))
    assert ordered.lookup("odom", "base_link", 100 * MS)[0, 3] == pytest.approx(42.0)
    (span,) = ordered.spans()
    assert (span.samples, span.first_ns, span.last_ns) == (20, 0, 950 * MS)
    assert (span.late, span.replaced) == (0, 1)
    # Each sample that came after a later stamp is counted (what `info` reports).
    late = sum(
        stamp < max(shuffled_stamps[:k], default=-1) for k, stamp in enumerate(shuffled_stamps)
    )
    assert late > 0
    assert shuffled.spans()[0].late == late


def test_no_extrapolation_says_by_how_much() -> None:
    history = _vehicle([(S, np.eye(4)), (2 * S, np.eye(4))])
    with pytest.raises(ExtrapolationError) as future:
        history.lookup("odom", "camera", 2 * S + 100 * MS)
    assert future.value.future
    assert future.value.edge == ("odom", "base_link")
    message = str(future.value)
    assert "/tf odom → base_link" in message
    assert "after its newest sample" in message
    assert "by 100.000 ms" in message
    assert "2.000000000 s" in message
    assert "\n" not in message
    with pytest.raises(ExtrapolationError, match=r"before its oldest sample .* by 250\.000 ms"):
        history.camera_motion("camera", S - 250 * MS, S)
    assert isinstance(future.value, InputError)
    # One sample answers its own stamp only (tf2 too).
    single = _vehicle([(S, _yaw(0.0, x=5.0))])
    assert single.lookup("odom", "base_link", S)[0, 3] == 5.0
    with pytest.raises(ExtrapolationError, match=r"by 1 ns;"):
        single.lookup("odom", "base_link", S + 1)


def test_the_cache_window() -> None:
    history = TransformHistory(cache_ns=1 * S)
    for k in range(30):  # 3 s at 10 Hz: samples older than 1 s behind the newest are dropped
        history.add(*_odom(k * 100 * MS, _analytic(k / 10)))
    assert history.spans()[0].first_ns == 1900 * MS
    with pytest.raises(ExtrapolationError, match="older samples left the cache window"):
        history.lookup("odom", "base_link", 1 * S)
    with pytest.raises(TransformDataError) as old:
        history.add(*_odom(1800 * MS, np.eye(4)))
    assert "/tf odom → base_link at 1.800000000 s" in str(old.value)
    assert "1100.000 ms older than its newest sample" in str(old.value)
    assert "the cache keeps 1 s" in str(old.value)
    for bad in (0, -1, 1.5, True):
        with pytest.raises(TransformDataError, match="cache window must be > 0"):
            TransformHistory(cache_ns=bad)  # type: ignore[arg-type]
    assert TransformHistory(cache_ns=np.int64(5)).cache_ns == 5


def test_a_frame_has_one_parent() -> None:
    history = _vehicle([(0, np.eye(4))])
    with pytest.raises(
        TransformDataError, match="'base_link' already has the parent 'odom' on /tf"
    ):
        history.add(0, StaticTransform("map", "base_link", np.eye(4)))
    with pytest.raises(
        TransformDataError, match="'camera' already has the parent 'base_link' on /tf_static"
    ):
        history.add(0, StaticTransform("odom", "camera", np.eye(4)))
    # A /tf_static edge for a /tf child is refused; the other edges of the batch are kept.
    with pytest.raises(TransformDataError, match="/tf_static map → base_link"):
        history.add_static(
            [
                StaticTransform("map", "base_link", np.eye(4)),
                StaticTransform("camera", "lens", np.eye(4)),
            ]
        )
    assert "lens" in history.frames
    with pytest.raises(TransformDataError, match="would make a loop"):
        history.add(0, StaticTransform("camera", "odom", np.eye(4)))
    with pytest.raises(TransformDataError, match="not an edge between two named frames"):
        history.add(0, StaticTransform("", "x", np.eye(4)))
    with pytest.raises(CalibrationError, match="the rotation is not a rotation matrix"):
        history.add(0, StaticTransform("odom", "wheel", np.diag([2.0, 1.0, 1.0, 1.0])))
    # extend keeps what it can and returns a line per refusal.
    problems = history.extend(
        [_odom(S, np.eye(4)), (S, StaticTransform("map", "base_link", np.eye(4)))]
    )
    assert len(problems) == 1
    assert "one parent" in problems[0]
    assert history.spans()[0].last_ns == S


def test_a_chain_that_does_not_reach_the_camera() -> None:
    history = _vehicle([(0, np.eye(4)), (S, np.eye(4))])
    history.add_static([StaticTransform("rig", "stereo_left", np.eye(4))])
    with pytest.raises(TransformChainError) as error:
        history.camera_motion("stereo_left", 0, S, fixed_frame="odom")
    message = str(error.value)
    assert "'stereo_left' to 'odom'" in message
    assert "frames known: base_link, camera, odom, rig, stereo_left" in message
    with pytest.raises(TransformChainError, match="camera frame 'left' is in no /tf"):
        history.camera_motion("left", 0, S)
    # stereo_left's own tree has no /tf edge: nothing moves it, so no motion (not identity).
    with pytest.raises(TransformChainError, match=r"holds no /tf edge .* odom → base_link"):
        history.camera_motion("stereo_left", 0, S)
    assert isinstance(error.value, CalibrationError)


def test_an_empty_tf_is_one_line() -> None:
    history = TransformHistory(TransformTree({}))
    history.add_static([StaticTransform("base_link", "camera", MOUNT)])
    with pytest.raises(TransformDataError) as error:
        history.camera_motion("camera", 0, S)
    assert str(error.value).startswith("no /tf transform received")
    with pytest.raises(TransformChainError, match="no /tf or /tf_static transform received"):
        TransformHistory().lookup("odom", "camera", 0)
    assert not history.ready(0)
    assert not history.ready(0, "camera")


def test_the_fixed_frame_is_odom_when_above_the_camera() -> None:
    history = _vehicle([(0, np.eye(4)), (S, _yaw(0.0, x=1.0))])
    # A localisation correction between the stamps: map → odom jumps by 5 m.
    history.add(0, StaticTransform("map", "odom", np.eye(4)))
    history.add(S, StaticTransform("map", "odom", _yaw(0.0, y=5.0)))
    assert history.fixed_frame("camera") == "odom"
    through_odom = history.camera_motion("camera", 0, S)
    np.testing.assert_allclose(through_odom[:3, 3], [0.0, 0.0, 1.0], atol=1e-12)
    through_map = history.camera_motion("camera", 0, S, fixed_frame="map")
    np.testing.assert_allclose(through_map[:3, 3], [-5.0, 0.0, 1.0], atol=1e-12)
    # Without odom the root of the camera's chain is the fixed frame.
    world = TransformHistory()
    world.add(0, StaticTransform("world", "camera", np.eye(4)))
    assert world.fixed_frame("camera") == "world"


def test_ready() -> None:
    history = _vehicle([(0, np.eye(4)), (S, np.eye(4))])
    history.add(3 * S, StaticTransform("odom", "arm", np.eye(4)))
    assert history.ready(S, "camera")
    assert not history.ready(S + 1, "camera")
    assert not history.ready(S, "arm_tool")
    assert history.ready(2 * S, "arm")
    # Without a frame: every /tf edge until a lookup picks the chain, then that chain's edges.
    fresh = _vehicle([(0, np.eye(4)), (S, np.eye(4))])
    fresh.add(S // 2, StaticTransform("odom", "arm", np.eye(4)))
    assert not fresh.ready(S)
    fresh.camera_motion("camera", 0, S)
    assert fresh.ready(S)
    assert not fresh.ready(S + 1)


def test_check_rotation_is_numpys_rule() -> None:
    """check_rotation in plain floats accepts exactly what allclose(R·Rᵀ, I) and det ≈ 1 do."""
    rng = np.random.default_rng(8)
    accepted = 0
    for scale in np.repeat([1e-4, 3e-4, 5e-4, 1e-3, 3e-3], 60):
        rotation = _yaw(float(rng.uniform(-3, 3)))[:3, :3] + rng.normal(0, scale, (3, 3))
        expected = bool(
            np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-3)
            and abs(np.linalg.det(rotation) - 1) < 1e-3
        )
        try:
            check_rotation(rotation, "R")
            got = True
        except CalibrationError:
            got = False
        assert got == expected
        accepted += got
    assert 60 < accepted < 240  # both sides of the boundary were tried
    for bad in (np.diag([1.0, 1.0, -1.0]), np.full((3, 3), np.nan), np.eye(4)):
        with pytest.raises(CalibrationError, match=r"^R is not a rotation matrix$"):
            check_rotation(bad, "R")


def test_the_readme_example_prints_what_it_says(capsys: pytest.CaptureFixture[str]) -> None:
    from test_readme import readme_block

    exec(readme_block("tf-history-example", "python"), {})
    assert capsys.readouterr().out == "[0. 0. 1.]\n"
