"""The flicker stage's windows: which frames make a window, and what bad input leaves.

Every window's numbers are compared with a plain numpy re-computation from the definition
(the per-pixel sample standard deviation, ``ddof = 1``, over the window's frames, on a smooth
plane where no mask applies); the stage's rules (a gap, an out-of-order stamp, a missing
method, a window of one frame, a moving camera) each give one problem line and lose nothing
already collected.
"""

from __future__ import annotations

import numpy as np
import pytest

from dispeval_ros.core.camera import Camera
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.stream.config import CoreConfig
from dispeval_ros.stream.flicker import (
    STATIC_TRANSLATION_M,
    FlickerInput,
    FlickerOutcome,
    FlickerStage,
)

H, W, SIGMA = 24, 32, 0.4
CAMERA = Camera(f=500.0, baseline=0.1)
MS = 1_000_000
PLANE = (30.0 + 0.05 * np.arange(W, dtype=np.float32))[None, :].repeat(H, 0)


def noisy_frames(count: int, seed: int = 1) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [(PLANE + rng.normal(0, SIGMA, PLANE.shape)).astype(np.float32) for _ in range(count)]


def feed(stage: FlickerStage, stamps: list[int], maps: dict[str, list[np.ndarray | None]]):
    """Each frame through the stage (a method's None: not scored there); all outcomes joined."""
    out = FlickerOutcome()
    for index, stamp in enumerate(stamps):
        frames = {
            m: stage.prepare(seq[index], None, 0.0)
            for m, seq in maps.items()
            if seq[index] is not None
        }
        step = stage.add(FlickerInput(stamp, frames, None, CAMERA, "left_optical"))
        out.windows += step.windows
        out.problems += step.problems
    tail = stage.finish()
    out.windows += tail.windows
    out.problems += tail.problems
    return out


def numpy_spread(maps: list[np.ndarray]) -> np.ndarray:
    """Per pixel, the sample std (ddof 1) of the window's disparities: the definition."""
    return np.std(np.stack([m.astype(np.float64) for m in maps]), axis=0, ddof=1)


def test_full_windows_equal_numpy_and_the_tail_window_is_partial() -> None:
    maps = noisy_frames(12)
    out = feed(FlickerStage(5), [k * 100 * MS for k in range(12)], {"a": list(maps)})
    assert out.problems == []
    assert [(w.start, w.stamp, w.frames) for w in out.windows] == [
        (0, 400 * MS, 5), (500 * MS, 900 * MS, 5), (1000 * MS, 1100 * MS, 2),
    ]  # fmt: skip
    for window, (lo, hi) in zip(out.windows, [(0, 5), (5, 10), (10, 12)], strict=True):
        spread = numpy_spread(maps[lo:hi])
        assert window.sums.column("all", "n_residual") == H * W  # no mask applies here
        assert window.sums.column("all", "sum") == pytest.approx(spread.sum(), rel=1e-6)
        assert window.sums.column("all", "sum_sq") == pytest.approx((spread**2).sum(), rel=1e-6)
        depth = numpy_spread([CAMERA.fb / m for m in maps[lo:hi]])
        assert window.sums.column("all", "sum_abs_z") == pytest.approx(depth.sum(), rel=1e-5)
    pooled = out.windows[0].sums + out.windows[1].sums + out.windows[2].sums
    every = np.concatenate(
        [numpy_spread(maps[a:b]).ravel() for a, b in ((0, 5), (5, 10), (10, 12))]
    )
    assert pooled.summary("all")["mean"] == pytest.approx(every.mean(), rel=1e-6)


def test_a_constant_bias_flickers_what_the_unbiased_method_flickers() -> None:
    maps = noisy_frames(5)
    out = feed(FlickerStage(5), [k * 100 * MS for k in range(5)],
               {"plain": list(maps), "biased": [m + np.float32(1.5) for m in maps]})  # fmt: skip
    plain, biased = (w.sums.summary("all") for w in out.windows)
    assert biased["mean"] == pytest.approx(plain["mean"], rel=1e-4)
    assert biased["rms"] == pytest.approx(plain["rms"], rel=1e-4)


def test_the_same_map_every_frame_flickers_exactly_zero() -> None:
    out = feed(FlickerStage(5), [k * 100 * MS for k in range(5)], {"true": [PLANE] * 5})
    assert out.windows[0].sums.column("all", "sum_sq") == 0.0
    assert out.windows[0].sums.column("all", "n_residual") == H * W


def test_an_out_of_order_frame_is_one_line_and_the_window_before_is_kept() -> None:
    maps = noisy_frames(6)
    stamps = [0, 100 * MS, 200 * MS, 150 * MS, 300 * MS, 400 * MS]
    out = feed(FlickerStage(5), stamps, {"a": list(maps)})
    assert len(out.problems) == 1
    assert "frame at 150000000" in out.problems[0][1]
    assert "not after" in out.problems[0][1]
    assert [(w.start, w.stamp, w.frames) for w in out.windows] == [
        (0, 200 * MS, 3), (300 * MS, 400 * MS, 2),
    ]  # fmt: skip
    spread = numpy_spread(maps[:3])
    assert out.windows[0].sums.column("all", "sum") == pytest.approx(spread.sum(), rel=1e-6)


def test_a_window_of_one_frame_is_one_line_and_nothing_else_is_lost() -> None:
    maps = noisy_frames(4)
    stamps = [0, 100 * MS, 200 * MS, 900 * MS]  # 700 ms: more than the pair gap
    out = feed(FlickerStage(5), stamps, {"a": list(maps)})
    assert [(w.start, w.frames) for w in out.windows] == [(0, 3)]
    assert len(out.problems) == 2
    early, single = (text for _, text in out.problems)
    assert "a: flicker window 0 → 200000000 (3 frames) ended early" in early
    assert "700 ms later, more than the pair gap" in early
    assert "(1 frame) ended by the end of the stream: not scored" in single


def test_a_missing_method_ends_only_its_own_window() -> None:
    maps = noisy_frames(5)
    out = feed(FlickerStage(5), [k * 100 * MS for k in range(5)],
               {"a": list(maps), "b": [maps[0], maps[1], None, maps[3], maps[4]]})  # fmt: skip
    assert sorted((w.method, w.start, w.frames) for w in out.windows) == [
        ("a", 0, 5), ("b", 0, 2), ("b", 300 * MS, 2),
    ]  # fmt: skip
    assert out.problems == [("b", "b: flicker window 0 → 100000000 (2 frames) ended early: "
                                   "b not scored at 200000000")]  # fmt: skip


def test_a_camera_that_moves_within_a_window_is_not_scored() -> None:
    stage = FlickerStage(3)

    def motion(camera_frame: str, t0: int, t1: int) -> np.ndarray:
        assert camera_frame == "left_optical"
        moved = np.eye(4)
        moved[2, 3] = 2 * STATIC_TRANSLATION_M if t1 >= 400 * MS else 0.0
        return moved

    stage.motion = motion
    out = feed(stage, [k * 100 * MS for k in range(6)], {"a": noisy_frames(6)})
    assert [(w.start, w.frames) for w in out.windows] == [(0, 3)]
    assert len(out.problems) == 1
    assert (
        "a: flicker window 300000000 → 500000000 (3 frames) not scored: the camera moved 10 mm"
        in (out.problems[0][1])
    )


def test_a_window_waits_for_the_motion_source() -> None:
    stage = FlickerStage(2)
    known = {"until": 0}
    stage.motion = lambda frame, t0, t1: np.eye(4)
    stage.ready = lambda stamp, frame: stamp <= known["until"]
    frames = {"a": stage.prepare(PLANE, None, 0.0)}
    assert stage.add(FlickerInput(0, frames, None, CAMERA, "cam")).windows == []
    assert stage.add(FlickerInput(100 * MS, frames, None, CAMERA, "cam")).windows == []
    known["until"] = 100 * MS
    assert [
        w.stamp for w in stage.add(FlickerInput(200 * MS, frames, None, CAMERA, "cam")).windows
    ] == [100 * MS]
    assert [w.start for w in stage.finish().windows] == []  # the last frame alone: one line


@pytest.mark.parametrize("size", [1, -3])
def test_a_window_of_fewer_than_two_frames_is_refused_in_one_line(size: int) -> None:
    with pytest.raises(ConfigurationError, match="at least 2 frames"):
        CoreConfig(methods={"a": "/a"}, gt_topic="/gt", flicker=size)
