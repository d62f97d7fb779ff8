"""Real stereo_image_proc output scored as the DisparityImage message defines it.

The shared bags (``stereo-image-proc/``, ROS 1, recorded from the real BM and SGBM nodelets)
are read here with rosbags' own reader and deserializer, independent of the project's decoder,
and the numbers ``dispeval bag`` stores are recomputed in plain numpy from the definition:
valid = inside ``[min_disparity, max_disparity]`` (SGBM's valid 0.0 included), values
offset-corrected (``d = x_l − x_r − (cx_l − cx_r)``). Synthetic messages cover what the
recordings do not: a negative ``min_disparity``, a negative ``T`` and a CameraInfo pair with
``cx_r ≠ cx_l``; a make-bag round trip of a MiddEval3 scene with ``doffs`` 52 px covers the
writer.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from dispeval_ros import Camera, Evaluator, GroundTruthFree
from dispeval_ros.cli.main import main
from dispeval_ros.core.measures import DEFAULT_MEASURES
from dispeval_ros.io import read_disparity, write_pfm
from dispeval_ros.io.encoders import camera_info_to_msg, disparity_to_msg, image_to_msg
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import methods_for
from dispeval_ros.stream.core import CoreConfig, EvaluationCore

GT = "/stereo/ground_truth/disparity"
LEFT_INFO = "/stereo/left/camera_info"
RIGHT_INFO = "/stereo/right/camera_info"
METHODS = {"bm": "/stereo_bm/disparity", "sgbm": "/stereo_sgbm/disparity"}
WHOLE_BAG = "100000"  # seconds: the whole bag is one unit, whatever its stamps and log times
MU = 0.01  # px, the default μ of SZE
BAGS = {"sip_kitti.bag": 5, "sip_mb_doffs0.bag": 3}


def _float_image(image: Any) -> np.ndarray:
    """A little-endian 32FC1 ``sensor_msgs/Image`` as float64, rows cut to ``width``."""
    assert image.encoding == "32FC1"
    assert not image.is_bigendian
    rows = np.frombuffer(np.asarray(image.data, np.uint8).tobytes(), "<f4")
    return rows.reshape(image.height, image.step // 4)[:, : image.width].astype(np.float64)


def read_sip_bag(path: Path) -> tuple[dict[int, np.ndarray], dict[str, dict[int, Any]], float]:
    """GT by stamp, each method's messages by stamp, and ``cx_r − cx_l`` of the CameraInfo."""
    gts: dict[int, np.ndarray] = {}
    estimates: dict[str, dict[int, Any]] = {name: {} for name in METHODS}
    method_of = {topic: name for name, topic in METHODS.items()}
    cx: dict[str, float] = {}
    with AnyReader([path]) as reader:
        for connection, _, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            if connection.topic == GT:
                gts[stamp] = _float_image(msg)
            elif connection.topic in method_of:
                estimates[method_of[connection.topic]][stamp] = msg
            elif connection.topic in (LEFT_INFO, RIGHT_INFO):
                cx[connection.topic] = float(msg.P[2])
    return gts, estimates, cx[RIGHT_INFO] - cx[LEFT_INFO]


def expected_scores(gt: np.ndarray, msg: Any, doffs: float) -> dict[str, float]:
    """density, bmp (δ = 1) and mae under ``ignore``, from the message's definition."""
    values = _float_image(msg.image)
    gt_valid = np.isfinite(gt) & (gt > 0)
    with np.errstate(invalid="ignore"):
        valid = (
            np.isfinite(values)
            & (values >= np.float64(msg.min_disparity))
            & (values <= np.float64(msg.max_disparity))
        )
    both = gt_valid & valid
    error = np.abs(values[both] - doffs - gt[both])
    return {
        "density": both.sum() / gt_valid.sum(),
        "bmp": 100.0 * (error > 1.0).sum() / both.sum(),
        "mae": error.sum() / both.sum(),
    }


@pytest.fixture(scope="module", params=sorted(BAGS))
def scored_bag(
    request: pytest.FixtureRequest, shared_data: Path, tmp_path_factory: pytest.TempPathFactory
) -> tuple[str, Path, Path]:
    """One shared bag scored by ``dispeval bag`` under ``--missing ignore`` (its results)."""
    bag = shared_data / "stereo-image-proc" / request.param
    out = tmp_path_factory.mktemp("sip") / "out"
    methods = [arg for name, topic in METHODS.items() for arg in ("--method", f"{name}={topic}")]
    command = ["bag", str(bag), "--gt", GT, *methods, "--camera-info", LEFT_INFO, RIGHT_INFO]
    command += ["--criteria", "all", "--missing", "ignore", "--slice", WHOLE_BAG]
    command += ["--measures", "bmp", "mae", "sze", "bmpre", "--out", str(out), "--quiet"]
    assert main(command) == 0
    return request.param, bag, out


def test_every_frame_equals_numpy_reading_validity_as_the_range(
    scored_bag: tuple[str, Path, Path],
) -> None:
    name, bag, out = scored_bag
    gts, estimates, doffs = read_sip_bag(bag)
    assert doffs == 0.0  # both bags: cx_r = cx_l (see the data README)
    # the trap they hold: SGBM's valid 0.0 inside [min_disparity = 0, max], invalid = −1
    sgbm = [_float_image(msg.image) for msg in estimates["sgbm"].values()]
    assert sum(int((values == 0).sum()) for values in sgbm) > 0
    assert all(msg.min_disparity == 0.0 for msg in estimates["sgbm"].values())
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        stamps = store.stamps(sequence)
        assert len(stamps) == BAGS[name]
        assert stamps == sorted(gts)
        for stamp in stamps:
            stored = store.frame_scores(sequence, stamp)
            for method in METHODS:
                expected = expected_scores(gts[stamp], estimates[method][stamp], doffs)
                got = stored[method]["all"]
                for measure, value in expected.items():
                    assert got[measure] == pytest.approx(value, rel=1e-6), (
                        name, stamp, method, measure,
                    )  # fmt: skip


# -- synthetic messages ----------------------------------------------------------------------

STAMP = 1_700_000_000_000_000_000
TOPIC = "/m/disparity"
CAMERA = Camera(f=100.0, baseline=0.5)


def _core(camera_info: bool, measures: tuple[str, ...]) -> EvaluationCore:
    return EvaluationCore(
        CoreConfig(
            methods={"m": TOPIC},
            gt_topic=GT,
            left_info_topic=LEFT_INFO if camera_info else None,
            right_info_topic=RIGHT_INFO if camera_info else None,
            criteria=("all",),
            measures=measures,
            missing="ignore",
        )
    )


def _score(
    frames: list[tuple[np.ndarray, np.ndarray]],
    *,
    t: float = CAMERA.baseline,
    low: float,
    high: float,
    camera: Camera | None = None,
    measures: tuple[str, ...] = ("bmp", "mae", "sze"),
) -> tuple[list[dict[str, float]], list[str]]:
    """Each (GT, message values) frame through the core: its ``all`` scores, and the problems."""
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    core = _core(camera is not None, measures)
    joined = []
    for index, (gt, values) in enumerate(frames):
        stamp = STAMP + index * 100_000_000
        height, width = gt.shape
        if camera is not None:
            for topic, right in ((LEFT_INFO, False), (RIGHT_INFO, True)):
                info = camera_info_to_msg(typestore, camera, width, height, stamp, "l", right)
                core.push(topic, info)
        joined += core.push(GT, image_to_msg(typestore, gt, stamp, "l", "32FC1"))
        message = disparity_to_msg(typestore, values, stamp, "l", CAMERA.f, t, low, high)
        joined += core.push(TOPIC, message)
    joined += core.flush()
    results = [core.score(frame_set) for frame_set in joined]
    assert len(results) == len(frames)
    problems = [text for result in results for _, text in result.problems]
    return [dict(result.scores["m"]["all"]) for result in results], problems


def _numpy(
    gt: np.ndarray, values: np.ndarray, low: float, high: float, fb: float, doffs: float
) -> dict[str, float]:
    """bmp, mae and sze under ``ignore``: valid = [low, high], scored ``value − doffs``.

    SZE of a value whose depth is beyond infinity (``E + doffs < 0``) takes the far limit
    ``f·B/μ``, as ``E + doffs = 0`` does (the README's rule).
    """
    gt = gt.astype(np.float64)
    values = values.astype(np.float64)
    valid = np.isfinite(values) & (values >= low) & (values <= high)
    both = valid & np.isfinite(gt) & (gt > 0)
    d, e = gt[both], values[both] - doffs
    error = np.abs(e - d)
    z_gt = fb / (d + doffs + MU)
    z_est = fb / (np.maximum(e + doffs, 0.0) + MU)
    return {
        "density": both.sum() / (np.isfinite(gt) & (gt > 0)).sum(),
        "bmp": 100.0 * (error > 1.0).sum() / both.sum(),
        "mae": error.sum() / both.sum(),
        "sze": np.abs(z_gt - z_est).sum(),
    }


def _assert_close(got: dict[str, float], expected: dict[str, float]) -> None:
    for measure, value in expected.items():
        assert got[measure] == pytest.approx(value, rel=1e-9), measure


def _frame(seed: int, low: float) -> tuple[np.ndarray, np.ndarray]:
    """GT in [2, 30] px and an estimate on a 1/16 px grid from ``low`` − 1 (invalid) upwards."""
    rng = np.random.default_rng(seed)
    gt = rng.uniform(2.0, 30.0, (12, 20)).astype(np.float32)
    estimate = np.round((gt + rng.normal(0.0, 3.0, gt.shape)) * 16) / 16
    estimate = np.maximum(estimate, low - 1).astype(np.float32)
    estimate[0, :6] = [low - 1, low, low + 0.5, 0.0, -0.0, low - 0.0625]
    return gt, estimate


def test_negative_min_disparity_keeps_negative_valid_values() -> None:
    low, high = -8.0, 40.0
    frames = [_frame(seed, low) for seed in range(3)]
    assert any((values < 0).any() and (values >= low).any() for _, values in frames)
    scores, problems = _score(frames, low=low, high=high, camera=CAMERA)
    assert problems == []
    for got, (gt, values) in zip(scores, frames, strict=True):
        _assert_close(got, _numpy(gt, values, low, high, CAMERA.fb, 0.0))


@pytest.mark.parametrize(
    ("policy", "scored"),
    [
        ("interpolate", [3, -2, -2, 0, 0, 0, 4]),  # a gap takes the smaller (farther) neighbour
        ("thesis", [3, 0, -2, 0, 0, 0, 4]),  # a missing estimate is E = 0
        ("ignore", [3, None, -2, 0, None, None, 4]),  # left out
    ],
)
def test_every_policy_keeps_valid_zeros_and_negative_values(policy: str, scored: list) -> None:
    """Range [−8, 40]: −9 is missing, −2 and 0 are valid values (GT 5 everywhere)."""
    estimate = np.array([[3.0, -9.0, -2.0, 0.0, -9.0, -9.0, 4.0]], np.float32)
    gt = np.full(estimate.shape, 5.0, np.float32)
    scores = Evaluator(criteria=("all",), missing=policy).score(gt, estimate, est_range=(-8, 40))
    errors = [abs(value - 5.0) for value in scored if value is not None]
    assert scores["all"]["density"] == 4 / 7
    assert scores["all"]["mae"] == pytest.approx(sum(errors) / len(errors), rel=1e-12)


def test_negative_t_is_its_magnitude_said_once() -> None:
    """No CameraInfo: the camera is the message's f and |T|; one problem row for the topic."""
    frames = [_frame(seed, 0.0) for seed in range(3)]
    negative, problems = _score(frames, t=-CAMERA.baseline, low=0.0, high=63.0)
    positive, none = _score(frames, t=CAMERA.baseline, low=0.0, high=63.0)
    assert none == []
    (said,) = problems
    assert TOPIC in said
    assert "t = -0.5 < 0" in said
    assert negative == positive
    for got, (gt, values) in zip(negative, frames, strict=True):
        _assert_close(got, _numpy(gt, values, 0.0, 63.0, CAMERA.fb, 0.0))


def test_offset_corrected_values_with_cx_r_not_cx_l_are_offset_once() -> None:
    """``cx_r − cx_l = 4``: the message's ``d = x_l − x_r + 4``, its range on those values."""
    camera = Camera(f=100.0, baseline=0.5, doffs=4.0)
    low, high = 6.0, 40.0  # in the message's (offset-corrected) values
    frames = []
    for seed in range(3):
        gt, estimate = _frame(seed, low - camera.doffs)
        frames.append((gt, estimate + np.float32(camera.doffs)))  # x_l − x_r + doffs
    scores, problems = _score(
        frames, low=low, high=high, camera=camera, measures=("bmp", "mae", "sze", "mae_z")
    )
    assert problems == []
    for got, (gt, values) in zip(scores, frames, strict=True):
        expected = _numpy(gt, values, low, high, camera.fb, camera.doffs)
        _assert_close(got, expected)
        valid = (values >= low) & (values <= high)
        z_gt = camera.fb / (gt[valid].astype(np.float64) + camera.doffs)  # f·B/(D + doffs)
        z_est = camera.fb / values[valid].astype(np.float64)  # the message's Z = f·T/d
        assert got["mae_z"] == pytest.approx(np.abs(z_gt - z_est).mean(), rel=1e-9)


@pytest.mark.parametrize("policy", ["ignore", "thesis"])
def test_gt_free_measures_warp_with_the_offset_corrected_values_once(policy: str) -> None:
    """vpe, lrc of ``x_l − x_r + doffs`` with ``est_offset = doffs``: those of ``x_l − x_r``."""
    rng = np.random.default_rng(5)
    left = rng.integers(0, 256, (16, 48), dtype=np.uint8)
    right = rng.integers(0, 256, (16, 48), dtype=np.uint8)
    estimate = np.round(rng.uniform(-1.0, 12.0, left.shape) * 16).astype(np.float32) / 16
    free = GroundTruthFree(("all",), policy)
    pair = free.pair(left, right)
    views = {"est_range": (0.0, 11.0), "right_range": (0.0, 11.0)}
    raw = free.score(pair, estimate, est_right=estimate, **views)
    doffs = np.float32(4.0)
    views = {"est_range": (4.0, 15.0), "right_range": (4.0, 15.0), "est_offset": 4.0}
    shifted = free.score(pair, estimate + doffs, est_right=estimate + doffs, **views)
    np.testing.assert_array_equal(shifted.sums, raw.sums)
    unshifted = free.score(pair, estimate + doffs, est_range=(4.0, 15.0))
    assert unshifted["gtfree:all"]["vpe"] != raw["gtfree:all"]["vpe"]  # the offset matters


def test_pixel_measures_need_no_camera() -> None:
    """f = 0 in the message and no CameraInfo: bmp and mae as with a camera, sze nan, said."""
    frames = [_frame(seed, 0.0) for seed in range(2)]
    scores, problems = _score(frames, t=0.0, low=0.0, high=63.0)
    assert len(problems) == 2
    assert all("depth measures not scored" in text for text in problems)
    for got, (gt, values) in zip(scores, frames, strict=True):
        expected = _numpy(gt, values, 0.0, 63.0, 1.0, 0.0)
        assert np.isnan(got["sze"])
        for measure in ("density", "bmp", "mae"):
            assert got[measure] == pytest.approx(expected[measure], rel=1e-9), measure


# -- make-bag round trip: a MiddEval3 scene with doffs ≠ 0 ----------------------------------


def test_make_bag_of_a_middeval3_scene_with_doffs_scores_as_its_files(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scene = shared_data / "middeval3-training-Q" / "Teddy"  # doffs = 52 px
    bag = tmp_path / "teddy"
    assert main(["make-bag", str(bag), "--scene", str(scene), "--json"]) == 0
    written = json.loads(capsys.readouterr().out)
    options = ["--criteria", "all", "--missing", "thesis", "--measures", *DEFAULT_MEASURES]
    command = ["bag", str(bag), "--gt", written["gt"], "--camera-info", *written["camera_info"]]
    for name, topic in written["methods"].items():
        command += ["--method", f"{name}={topic}"]
    out = tmp_path / "out"
    assert main([*command, *options, "--slice", WHOLE_BAG, "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()

    gt = read_disparity(scene / "disp0GT.pfm")
    left = cv2.imread(str(scene / "im0.png"), cv2.IMREAD_GRAYSCALE)
    right = cv2.imread(str(scene / "im1.png"), cv2.IMREAD_GRAYSCALE)
    methods = {m.name: m for m in methods_for(gt.shape[1], float(gt[np.isfinite(gt)].max()))}
    assert set(methods) == set(written["methods"])
    with AnyReader([bag]) as reader:  # the messages follow the definition: + doffs, range too
        for connection, _, raw in reader.messages():
            if connection.msgtype != "stereo_msgs/msg/DisparityImage":
                continue
            msg = reader.deserialize(raw, connection.msgtype)
            method = methods[connection.topic.split("/")[2]]
            raw_values = method.compute(left, right).astype(np.float64)
            np.testing.assert_array_equal(_float_image(msg.image), raw_values + 52.0)
            assert msg.min_disparity == method.min_disparity + 52.0
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        (stamp,) = store.stamps(sequence)
        from_bag = store.frame_scores(sequence, stamp)
    for name, method in methods.items():
        estimate = method.compute(left, right)
        # valid 0 of the message's range; a file's 0 means missing: the smallest normal float
        estimate = np.where(estimate == 0, np.finfo(np.float32).tiny, estimate)
        write_pfm(tmp_path / f"{name}.pfm", estimate)
        files = ["--gt", str(scene / "disp0GT.pfm"), "--est", str(tmp_path / f"{name}.pfm")]
        code = main(["eval", *files, "--calib", str(scene / "calib.txt"), *options, "--json"])
        assert code == 0
        from_files = json.loads(capsys.readouterr().out)["frames"][0]["criteria"]["all"]
        for measure, value in from_files.items():
            stored = from_bag[name]["all"][measure]
            if value is None:
                assert np.isnan(stored), (name, measure)
            else:
                assert stored == pytest.approx(value, rel=1e-12, abs=1e-12), (name, measure)
