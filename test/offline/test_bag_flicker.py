"""``dispeval bag --flicker``: a static camera's flicker from a bag, checked against numpy.

The bag is make-bag's synthetic rig standing still: every frame has the same pose on /tf
(odom → base_link) and the same ground truth, a smooth plane (no depth edge), and its images
carry per-frame sensor noise of at most ±3 grey levels (below the photometric threshold), so
no mask applies and every pixel counts. Methods: ``true`` publishes the ground truth,
``noisy`` the ground truth plus per-frame noise N(0, σ), ``biased`` the same plus 1.5 px.
Each stored window equals ``np.std(stack, axis=0, ddof=1)`` of the maps the bag was made of;
the pooled flicker is the sum of its windows; a moving camera (with --egomotion) is said and
not scored; a window of one frame is refused in one line.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from dispeval_ros.cli.main import main
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import (
    GT_TOPIC,
    LEFT_IMAGE,
    LEFT_INFO,
    RIGHT_IMAGE,
    RIGHT_INFO,
    disparity_topic,
    estimates_from,
    synthetic_frames,
    write_bag,
)
from dispeval_ros.offline.static_bag import static_frames
from dispeval_ros.testbed.methods import default_methods

FRAMES, WIDTH, HEIGHT, SIGMA, BIAS = 10, 96, 48, 0.3, 1.5
METHODS = ("true", "noisy", "biased")
PLANE = (20.0 + 0.02 * np.arange(WIDTH, dtype=np.float32))[None, :].repeat(HEIGHT, 0)


def c4(n: int) -> float:
    """E[s] / σ of the sample std of n normal samples (ddof 1)."""
    return math.sqrt(2 / (n - 1)) * math.gamma(n / 2) / math.gamma((n - 1) / 2)


@pytest.fixture(scope="module")
def root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """ROOT/static (the rig standing still) and ROOT/moving (the same frames, the drive's /tf)."""
    root = tmp_path_factory.mktemp("flicker")
    drive = list(synthetic_frames(FRAMES, WIDTH, HEIGHT, 10.0, seed=4))
    first = drive[0]
    still = [  # the rig standing still: sensor noise ±3 grey levels per frame, one pose
        dataclasses.replace(f, gt=PLANE) for f in static_frames(first, FRAMES, 10.0, 3, seed=1)
    ]
    noise = np.random.default_rng(2)
    for name in METHODS:
        (root / name).mkdir()
    for index in range(FRAMES):
        shake = noise.normal(0, SIGMA, PLANE.shape).astype(np.float32)
        maps = {"true": PLANE, "noisy": PLANE + shake, "biased": PLANE + shake + np.float32(BIAS)}
        for name, values in maps.items():
            np.save(root / name / f"{index:06d}.npy", values.astype(np.float32))
    sources = [estimates_from(name, root / name) for name in METHODS]
    for name, frames in (("static", still), ("moving", [
        dataclasses.replace(s, odometry=d.odometry) for s, d in zip(still, drive, strict=True)
    ])):  # fmt: skip
        write_bag(root / name, iter(frames), storage="rosbag2-sqlite3",
                  methods=default_methods(WIDTH)[:1], estimates=sources)  # fmt: skip
    (root / "fb").write_text(repr(first.camera.fb))
    return root


def command(bag: Path, out: Path, *extra: str) -> list[str]:
    return [
        "bag", str(bag), "--gt", GT_TOPIC,
        *(item for m in METHODS for item in ("--method", f"{m}={disparity_topic(m)}")),
        "--camera-info", LEFT_INFO, RIGHT_INFO, "--left-image", LEFT_IMAGE,
        "--right-image", RIGHT_IMAGE, "--gt-free-criteria", "all", "--criteria", "all",
        "--out", str(out), "--quiet", *extra,
    ]  # fmt: skip


@pytest.fixture(scope="module")
def static_run(root: Path) -> Path:
    assert main(command(root / "static", root / "res", "--flicker")) == 0
    return root / "res"


def maps(root: Path, method: str, indices: range) -> np.ndarray:
    return np.stack([np.load(root / method / f"{i:06d}.npy").astype(np.float64) for i in indices])


def test_each_window_equals_numpy_and_the_true_map_flickers_zero(
    root: Path, static_run: Path
) -> None:
    fb = float((root / "fb").read_text())
    with ResultsStore.open(static_run) as store:
        series = store.flicker_series("static")
    assert series is not None
    assert set(series) == set(METHODS)
    connection = sqlite3.connect(static_run / "results.sqlite")
    stamps = [s for (s,) in connection.execute("SELECT DISTINCT stamp FROM frames ORDER BY stamp")]
    connection.close()
    for method in METHODS:
        windows = series[method]
        assert [(w.start, w.stamp, w.frames) for w in windows] == [
            (stamps[0], stamps[4], 5), (stamps[5], stamps[9], 5),
        ]  # fmt: skip
        for window, indices in zip(windows, (range(0, 5), range(5, 10)), strict=True):
            stack = maps(root, method, indices)
            spread = np.std(stack, axis=0, ddof=1)
            depth = np.std(fb / stack, axis=0, ddof=1)
            sums = window.sums
            assert sums.criteria == ("all",)
            assert sums.column("all", "n_residual") == WIDTH * HEIGHT  # no mask applies
            assert sums.column("all", "sum") == pytest.approx(spread.sum(), rel=1e-6, abs=1e-9)
            assert sums.column("all", "sum_sq") == pytest.approx(
                (spread**2).sum(), rel=1e-6, abs=1e-9
            )
            assert sums.column("all", "sum_abs_z") == pytest.approx(depth.sum(), rel=1e-5, abs=1e-9)
            for t in sums.thresholds:
                assert sums.column("all", f"bad_{t:g}") == np.count_nonzero(spread > t)
            if method == "true":
                assert sums.column("all", "sum_sq") == 0.0


def test_summary_json_pools_the_windows_and_noise_reads_as_c4_sigma(static_run: Path) -> None:
    document = json.loads((static_run / "summary.json").read_text())
    entry = document["sequences"][0]["flicker"]
    assert entry["label"] == "temporal noise of a static camera, not accuracy"
    with ResultsStore.open(static_run) as store:
        series = store.flicker_series("static")
    assert series is not None
    for method in METHODS:
        mine = entry["methods"][method]
        assert (mine["windows"], mine["frames"]) == (2, FRAMES)
        added = series[method][0].sums.sums + series[method][1].sums.sums
        assert mine["sums"]["gtfree:all"] == added[0].tolist()
        assert mine["columns"] == list(series[method][0].sums.columns)
    noisy = entry["methods"]["noisy"]["criteria"]["gtfree:all"]
    biased = entry["methods"]["biased"]["criteria"]["gtfree:all"]
    assert entry["methods"]["true"]["criteria"]["gtfree:all"]["mean"] == 0.0
    assert noisy["mean"] == pytest.approx(c4(5) * SIGMA, rel=0.02)
    assert biased["mean"] == pytest.approx(noisy["mean"], rel=1e-4)  # a bias is no flicker
    assert biased["rms"] == pytest.approx(noisy["rms"], rel=1e-4)


def test_a_camera_moving_on_tf_is_said_and_not_scored(root: Path) -> None:
    out = root / "res-moving"
    assert main(command(root / "moving", out, "--flicker", "--egomotion")) == 0
    with ResultsStore.open(out) as store:
        assert store.flicker_series("moving") == {}
        problems = [p.message for p in store.problems("moving")]
    moved = [p for p in problems if "not scored: the camera moved" in p]
    assert len(moved) == 2 * len(METHODS)  # each window of each method, one line
    assert "more than a static camera's 5 mm and 0.05°" in moved[0]


def test_the_static_camera_on_tf_scores_as_without_it(root: Path, static_run: Path) -> None:
    out = root / "res-tf"
    assert main(command(root / "static", out, "--flicker", "--egomotion")) == 0
    with ResultsStore.open(out) as store, ResultsStore.open(static_run) as plain:
        mine, theirs = store.flicker("static"), plain.flicker("static")
    assert mine is not None
    assert theirs is not None
    assert mine.keys() == theirs.keys()
    for method, (windows, frames, sums) in mine.items():
        assert (windows, frames) == theirs[method][:2]
        assert np.array_equal(sums.sums, theirs[method][2].sums)


def test_windows_never_span_units(root: Path, static_run: Path) -> None:
    out = root / "res-units"
    assert main(command(root / "static", out, "--flicker", "--slice", "0.3")) == 0
    with ResultsStore.open(out) as store:
        series = store.flicker_series("static")
        problems = [p.message for p in store.problems("static")]
    assert series is not None
    counts = sorted(w.frames for w in series["noisy"])
    singles = [p for p in problems if p.startswith("noisy:") and "(1 frame)" in p]
    assert max(counts) <= 3
    assert sum(counts) + len(singles) == FRAMES


def test_a_window_of_one_frame_is_one_line(root: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(command(root / "static", root / "res-one", "--flicker", "1")) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "Traceback" not in err[0]
    assert "--flicker must be 0 (off) or a window of at least 2 frames" in err[0]
    assert not (root / "res-one" / "results.sqlite").exists()


@pytest.mark.parametrize(("workers", "size"), [(1, 5), (3, 5), (2, 4)])
def test_live_statuses_carry_the_windows_and_the_summarizer_stores_those_of_the_bag(
    root: Path, tmp_path: Path, workers: int, size: int
) -> None:
    """Frames scored side by side reach the flicker stage in the join's order all the same;
    with windows of 4 the last one (2 frames) closes when the stream stops, and is kept too."""
    from dispeval_ros.cli import streams
    from dispeval_ros.cli.main import build_parser
    from dispeval_ros.io.bags import BagSource
    from dispeval_ros.stream.runner import LiveEvaluator
    from dispeval_ros.stream.summarizer import SummarizerConfig, SummarizerCore
    from dispeval_ros.stream.vectors import (
        read_pairs,
        result_statuses,
        scores_from_status,
        window_only,
    )

    bag_out = tmp_path / "bag"
    line = command(root / "static", bag_out, "--flicker", str(size))
    config = streams.core_config(build_parser().parse_args(line), "bags")
    assert config.flicker == size
    assert main(line) == 0
    results = []
    live = LiveEvaluator(config, results.append, queue_size=100_000, workers=workers)
    with BagSource(root / "static") as source:
        for topic, log_ns, msg in source.messages(list(config.topics)):
            live.push(topic, msg, received=log_ns)
    live.stop(flush=True)
    core = SummarizerCore(SummarizerConfig(tmp_path / "live", every_n=3), {"run": "live"})
    for result in results:
        scores, pairs, motion, flicker = {}, {}, {}, {}
        for status in result_statuses(result, config.methods):
            if not window_only(status):  # (a window closed alone: the tail's)
                scores[status.name] = scores_from_status(status.values)
            read_pairs(status, pairs, motion, flicker=flicker)
        assert {w.method for w in result.flicker} == set(flicker)
        core.add(result.stamp, scores, None, pairs, motion, flicker=flicker)
    core.finish()
    with ResultsStore.open(tmp_path / "live") as store:
        live_windows = store.flicker(store.sequences()[0])
    with ResultsStore.open(bag_out) as store:
        bag_windows = store.flicker("static")
    assert bag_windows is not None
    assert all(frames == FRAMES for _, frames, _ in bag_windows.values())
    assert live_windows is not None
    assert bag_windows is not None
    assert live_windows.keys() == bag_windows.keys()
    for method, (windows, frames, sums) in bag_windows.items():
        assert live_windows[method][:2] == (windows, frames)
        assert np.array_equal(live_windows[method][2].sums, sums.sums)  # exact through the text


def test_make_bag_static_records_one_frame_n_times_with_bounded_sensor_noise(
    tmp_path: Path,
) -> None:
    from dispeval_ros.io.bags import BagSource
    from dispeval_ros.io.messages import image_from_msg, stamp_ns

    bag = tmp_path / "still"
    assert main([
        "make-bag", str(bag), "--static", "4", "--sensor-noise", "2", "--width", "96",
        "--height", "48", "--no-lidar", "--storage", "rosbag2-sqlite3",
    ]) == 0  # fmt: skip
    with BagSource(bag) as source:
        lefts = [(stamp_ns(m.header), image_from_msg(m, LEFT_IMAGE).array)
                 for _, _, m in source.messages([LEFT_IMAGE])]  # fmt: skip
        gts = [image_from_msg(m, GT_TOPIC).array for _, _, m in source.messages([GT_TOPIC])]
    assert [s - lefts[0][0] for s, _ in lefts] == [0, 100_000_000, 200_000_000, 300_000_000]
    truth = next(iter(synthetic_frames(1, 96, 48, 10.0, seed=0, odometry=False))).left
    for _, image in lefts:
        assert np.abs(image.astype(int) - truth.astype(int)).max() <= 2
    assert not np.array_equal(lefts[0][1], lefts[1][1])  # fresh noise each frame
    assert all(np.array_equal(g, gts[0], equal_nan=True) for g in gts)
    out = tmp_path / "res"
    assert main([
        "bag", str(bag), "--gt", GT_TOPIC, "--method", f"bm_fast={disparity_topic('bm_fast')}",
        "--camera-info", LEFT_INFO, RIGHT_INFO, "--flicker", "4", "--out", str(out), "--quiet",
    ]) == 0  # fmt: skip
    with ResultsStore.open(out) as store:
        flicker = store.flicker(store.sequences()[0])
    assert flicker is not None
    assert flicker["bm_fast"][:2] == (1, 4)
    assert flicker["bm_fast"][2].criteria == ("all",)  # no images given: every pixel


def test_sensor_noise_without_static_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["make-bag", str(tmp_path / "x"), "--sensor-noise", "3"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["dispeval make-bag: error: --sensor-noise G goes with --static N"]
    assert not (tmp_path / "x").exists()


def test_without_ground_truth_or_camera_info_the_windows_are_the_same(
    root: Path, static_run: Path
) -> None:
    """Flicker needs no GT; the depths' camera then comes from the DisparityImages' f and t."""
    out = root / "res-gt-free"
    line = command(root / "static", out, "--flicker")
    for option, count in (("--gt", 2), ("--camera-info", 3), ("--criteria", 2)):
        at = line.index(option)
        del line[at : at + count]
    assert main(line) == 0
    with ResultsStore.open(out) as store, ResultsStore.open(static_run) as plain:
        mine, theirs = store.flicker("static"), plain.flicker("static")
    assert mine is not None
    assert theirs is not None
    for method, (windows, frames, sums) in theirs.items():
        assert mine[method][:2] == (windows, frames)
        depth = [sums.columns.index(c) for c in ("sum_abs_z", "sum_sq_z")]
        pixels = [i for i in range(len(sums.columns)) if i not in depth]
        np.testing.assert_array_equal(mine[method][2].sums[:, pixels], sums.sums[:, pixels])
        # the DisparityImage's f and t are float32, the CameraInfo's float64
        np.testing.assert_allclose(mine[method][2].sums[:, depth], sums.sums[:, depth], rtol=1e-6)
