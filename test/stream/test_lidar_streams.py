"""Robot mode: LiDAR ground truth through the stream core (``dispeval bag --gt-cloud``).

The bag is the test-bed's synthetic drive with its simulated LiDAR; expected scores are
computed directly (scan → projection with the known mounting → evaluator), without the bag,
the messages or /tf_static.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore
from sample_feed import stored_scores

from dispeval_ros.cli.main import main
from dispeval_ros.core.projection import CloudFilter, project_cloud, rectified_projection
from dispeval_ros.core.transforms import StaticTransform, matrix_from_pose
from dispeval_ros.io.encoders import (
    camera_info_to_msg,
    cloud_to_msg,
    disparity_to_msg,
    tf_static_to_msg,
)
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import (
    CAMERA_FRAME,
    CLOUD_TOPIC,
    LEFT_INFO,
    LIDAR_FRAME,
    RIGHT_INFO,
    START_NS,
    disparity_topic,
    static_transforms,
    synthetic_frames,
    write_bag,
)
from dispeval_ros.stream.core import CoreConfig, EvaluationCore
from dispeval_ros.testbed import default_methods, driving_setup, driving_world_at, render_stereo
from dispeval_ros.testbed.lidar import LidarModel, lidar_to_camera, simulate_scan

WIDTH, HEIGHT, FRAMES, FPS = 248, 76, 4, 10.0
METHODS = ("bm_fast", "sgbm")


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("lidar") / "drive"
    methods = [m for m in default_methods(WIDTH) if m.name in METHODS]
    frames = synthetic_frames(FRAMES, WIDTH, HEIGHT, FPS, seed=3, lidar=LidarModel())
    summary = write_bag(path, frames, methods=methods, fps=FPS)
    assert summary["gt_cloud"] == CLOUD_TOPIC
    return path


def _run_bag(drive: Path, out: Path, *extra: str) -> dict[tuple[int, str], Any]:
    args = ["bag", str(drive), "--gt-cloud", CLOUD_TOPIC, "--camera-info", LEFT_INFO, RIGHT_INFO]
    for name in METHODS:
        args += ["--method", f"{name}={disparity_topic(name)}"]
    assert main([*args, *extra, "--out", str(out), "--quiet"]) == 0
    return stored_scores(out)


def test_bag_with_cloud_gt_scores_like_a_direct_projection(drive: Path, tmp_path: Path) -> None:
    stored = _run_bag(drive, tmp_path / "out")
    assert len(stored) == FRAMES * len(METHODS)
    config = CoreConfig(
        methods={m: disparity_topic(m) for m in METHODS},
        gt_topic=CLOUD_TOPIC,
        gt_kind="pointcloud",
        left_info_topic=LEFT_INFO,
        right_info_topic=RIGHT_INFO,
    )
    evaluator = config.evaluator()
    world, rig = driving_setup(WIDTH, HEIGHT, FPS, 3)
    methods = {m.name: m for m in default_methods(WIDTH)}
    for index in range(FRAMES):
        world_t, rig_t = driving_world_at(world, rig, index / FPS)
        scan = simulate_scan(world_t, rig_t)
        k = np.array([[rig.f, 0, rig.cx, 0], [0, rig.f, rig.cy, 0], [0, 0, 1, 0]])
        matrix = rectified_projection(lidar_to_camera(rig_t), np.eye(3), k)
        gt = project_cloud(scan, matrix, (HEIGHT, WIDTH), rig.camera, CloudFilter()).disparity
        frame = render_stereo(world_t, rig_t, stamp=index / FPS, noise_seed=[3, index])
        stamp = START_NS + round(index * 1e9 / FPS)
        for name in METHODS:
            method = methods[name]
            estimate = method.compute(frame.left, frame.right)
            expected = evaluator.score(
                gt, estimate, rig.camera, est_range=(method.min_disparity, method.max_disparity)
            )
            got = stored[stamp, name]
            assert got.criteria == expected.criteria
            assert got.criteria == (
                "all",
                "occluded",
                "boundary",
                "interior",
                "0-10m",
                "10-30m",
                "30+m",
            )
            np.testing.assert_allclose(got.sums, expected.sums, rtol=1e-9, atol=1e-9)
            assert got["all"]["irmse"] == pytest.approx(expected["all"]["irmse"], rel=1e-9)


def test_explicit_extrinsic_equals_tf_static(drive: Path, tmp_path: Path) -> None:
    _world, rig = driving_setup(WIDTH, HEIGHT, FPS, 3)
    file = tmp_path / "extrinsic.txt"
    file.write_text("\n".join(" ".join(map(str, row)) for row in lidar_to_camera(rig).tolist()))
    via_tf = _run_bag(drive, tmp_path / "tf")
    explicit = _run_bag(drive, tmp_path / "file", "--extrinsic", str(file))
    unfiltered = _run_bag(drive, tmp_path / "raw", "--cloud-filter", "0")
    for key, scores in via_tf.items():
        np.testing.assert_allclose(explicit[key].sums, scores.sums, rtol=1e-9, atol=1e-9)
        assert unfiltered[key]["all"]["n"] > scores["all"]["n"]  # the filter removed points


def test_cloud_options_are_checked(drive: Path, tmp_path: Path, capsys: Any) -> None:
    base = ["bag", str(drive), "--method", f"sgbm={disparity_topic('sgbm')}", "--quiet"]
    assert main([*base, "--gt-cloud", CLOUD_TOPIC, "--out", str(tmp_path / "a")]) == 2
    assert "needs the left and right CameraInfo" in capsys.readouterr().err
    infos = ["--camera-info", LEFT_INFO, RIGHT_INFO]
    args = [*base, *infos, "--gt-cloud", CLOUD_TOPIC, "--cloud-filter", "7"]
    assert main([*args, "--out", str(tmp_path / "b")]) == 2
    assert "cloud filter must be 'W,G'" in capsys.readouterr().err
    args = [*base, *infos, "--gt", "/stereo/ground_truth/disparity", "--extrinsic", "x"]
    assert main([*args, "--out", str(tmp_path / "c")]) == 2
    assert "go with --gt-cloud" in capsys.readouterr().err


# -- bad input: one clear problem per frame, never fatal for the others ---------------------

TYPESTORE = get_typestore(Stores.ROS2_HUMBLE)
SMALL = (40, 60)  # rows, columns


def _core(**options: Any) -> EvaluationCore:
    config = CoreConfig(
        methods={"m": "/m"},
        gt_topic="/points",
        gt_kind="pointcloud",
        left_info_topic="/left",
        right_info_topic="/right",
        **options,
    )
    core = EvaluationCore(config)
    camera = rig_camera()
    for topic, right in (("/left", False), ("/right", True)):
        info = camera_info_to_msg(TYPESTORE, camera, SMALL[1], SMALL[0], 0, CAMERA_FRAME, right)
        core.push(topic, info)
    return core


def rig_camera() -> Any:
    from dispeval_ros.core import Camera

    return Camera(f=40.0, baseline=0.5)


# A LiDAR 0.3 m above the camera, looking forward: optical = (−y, −z − 0.3... ) see below.
LIDAR_TO_OPTICAL = np.array(
    [[0, -1, 0, 0.0], [0, 0, -1, -0.3], [1, 0, 0, 0.0], [0, 0, 0, 1]], dtype=np.float64
)


def _wall_cloud(depth: float = 10.0) -> np.ndarray:
    """A wall ``depth`` metres ahead of the LiDAR (x forward), filling the view."""
    y, z = np.meshgrid(np.linspace(-8, 8, 80), np.linspace(-5, 5, 60))
    return np.column_stack([np.full(y.size, depth), y.ravel(), z.ravel()]).astype(np.float32)


def _frame(core: EvaluationCore, stamp: int, cloud: Any) -> Any:
    disparity = np.full(SMALL, 2.0, np.float32)
    core.push("/points", cloud)
    message = disparity_to_msg(TYPESTORE, disparity, stamp, CAMERA_FRAME, 40.0, 0.5, 0, 64)
    (frame_set,) = core.push("/m", message) or core.flush()
    return core.score(frame_set)


def _tf(*edges: StaticTransform) -> Any:
    return tf_static_to_msg(TYPESTORE, list(edges), 0)


def test_chain_that_does_not_connect_names_the_frames_then_recovers() -> None:
    core = _core()
    mount = matrix_from_pose([0, 0, 1.8], [0, 0, 0, 1])
    core.push("/tf_static", _tf(StaticTransform("base_link", LIDAR_FRAME, mount)))
    cloud = cloud_to_msg(TYPESTORE, _wall_cloud(), 1, LIDAR_FRAME)
    result = _frame(core, 1, cloud)
    assert result.scores == {}
    (problem,) = result.problems
    message = problem[1]
    assert f"cloud frame '{LIDAR_FRAME}'" in message
    assert f"camera frame '{CAMERA_FRAME}'" in message
    assert "frames in /tf_static: base_link, velodyne" in message
    # The camera's edge arrives: the next frame scores.
    core.push("/tf_static", _tf(*static_transforms(LIDAR_TO_OPTICAL)))
    result = _frame(core, 2, cloud_to_msg(TYPESTORE, _wall_cloud(), 2, LIDAR_FRAME))
    assert result.problems == []
    # A 10 m wall seen from 0.3 m lower: disparity f·B/10 = 2 px everywhere.
    assert result.scores["m"]["all"]["mae"] == pytest.approx(0.0, abs=1e-5)


def test_cloud_without_z_then_a_good_cloud() -> None:
    core = _core(extrinsic=tuple(LIDAR_TO_OPTICAL.reshape(-1)))
    bad = cloud_to_msg(TYPESTORE, _wall_cloud(), 1, LIDAR_FRAME)
    bad.fields = [field for field in bad.fields if field.name != "z"]
    result = _frame(core, 1, bad)
    (problem,) = result.problems
    assert "PointCloud2 on /points: the cloud has no 'z' field (fields: x, y)" in problem[1]
    result = _frame(core, 2, cloud_to_msg(TYPESTORE, _wall_cloud(), 2, LIDAR_FRAME))
    assert result.problems == []
    assert result.scores["m"]["all"]["n"] > 0


def test_extrinsic_behind_the_camera_is_reported() -> None:
    turned = matrix_from_pose([0, 0, 0], [0, 1, 0, 0]) @ LIDAR_TO_OPTICAL  # 180° about y
    core = _core(extrinsic=tuple(turned.reshape(-1)))
    result = _frame(core, 1, cloud_to_msg(TYPESTORE, _wall_cloud(), 1, LIDAR_FRAME))
    (problem,) = result.problems
    assert "all 4800 points are behind the camera 'stereo_left'" in problem[1]
    assert "inverted" in problem[1]


def test_camera_info_of_another_size_is_reported() -> None:
    core = _core(extrinsic=tuple(LIDAR_TO_OPTICAL.reshape(-1)))
    info = camera_info_to_msg(TYPESTORE, rig_camera(), 80, 50, 0, CAMERA_FRAME, False)
    core.push("/left", info)
    result = _frame(core, 1, cloud_to_msg(TYPESTORE, _wall_cloud(), 1, LIDAR_FRAME))
    (problem,) = result.problems
    assert "CameraInfo on /left is 80×50 but the disparity is 60×40" in problem[1]


def test_camera_info_whose_r_is_not_a_rotation_is_reported_then_recovers() -> None:
    """A scaled R (2·I) would move every point to wrong pixels: refused per frame, as the
    extrinsic is (the same rotation check), naming the topic."""
    core = _core(extrinsic=tuple(LIDAR_TO_OPTICAL.reshape(-1)))
    info = camera_info_to_msg(TYPESTORE, rig_camera(), SMALL[1], SMALL[0], 0, CAMERA_FRAME, False)
    good_r = np.array(info.r, dtype=np.float64)
    info.r = (2.0 * np.eye(3)).reshape(-1)
    core.push("/left", info)
    result = _frame(core, 1, cloud_to_msg(TYPESTORE, _wall_cloud(), 1, LIDAR_FRAME))
    assert result.scores == {}
    (problem,) = result.problems
    assert "CameraInfo on /left: R is not a rotation matrix" in problem[1]
    assert "\n" not in problem[1]
    info.r = good_r
    core.push("/left", info)
    result = _frame(core, 2, cloud_to_msg(TYPESTORE, _wall_cloud(), 2, LIDAR_FRAME))
    assert result.problems == []
    assert result.scores["m"]["all"]["n"] > 0


def test_config_record_and_defaults() -> None:
    config = _core().config
    assert config.topics["/points"] == "sensor_msgs/msg/PointCloud2"
    assert config.topics["/tf_static"] == "tf2_msgs/msg/TFMessage"
    assert config.as_record()["cloud_filter"] == "7,0.1"
    evaluator = config.evaluator()
    assert evaluator.boundary_mode == "sparse"
    assert evaluator.depth_ranges == [(0.0, 10.0), (10.0, 30.0), (30.0, math.inf)]
    assert {"mae_z", "rmse_z", "absrel_z", "irmse"} <= set(evaluator.measures)
    explicit = CoreConfig(**{**config.__dict__, "extrinsic": tuple(np.eye(4).reshape(-1))})
    assert "/tf_static" not in explicit.topics


# -- the simulated LiDAR against the exact ray cast -------------------------------------------


def test_filtered_synthetic_lidar_agrees_with_the_exact_ray_cast() -> None:
    """< 0.5 % of the kept points disagree by > 1 px with the camera's exact view of them."""
    from dispeval_ros.testbed.lidar import check_scan

    world, rig = driving_setup(620, 188, 10.0, 0)
    checks = {str(chosen): [] for chosen in (CloudFilter(0), CloudFilter())}
    for index in range(0, 30, 5):
        world_t, rig_t = driving_world_at(world, rig, index / 10.0)
        for chosen in (CloudFilter(0), CloudFilter()):
            checks[str(chosen)].append(check_scan(world_t, rig_t, cloud_filter=chosen))
    kept = sum(c.kept for c in checks["7,0.1"])
    assert kept > 30_000
    assert sum(c.removed for c in checks["7,0.1"]) > 0.02 * kept
    assert sum(c.off_exact for c in checks["7,0.1"]) < 0.005 * kept
    unfiltered = sum(c.off_exact for c in checks["0"])
    assert unfiltered > 0.02 * sum(c.kept for c in checks["0"])  # the filter is needed


# -- real KITTI scans into a bag, and the demo ------------------------------------------------


@pytest.mark.data
def test_make_bag_from_a_kitti_lidar_scene(shared_data: Path, tmp_path: Path) -> None:
    from dispeval_ros.io.scenes import list_frames

    folder = shared_data / "kitti-lidar" / "stereo-rcnn-demo"
    bag = tmp_path / "kitti"
    assert main(["make-bag", str(bag), "--scene", str(folder), "--json"]) == 0
    out = tmp_path / "out"
    args = ["bag", str(bag), "--gt-cloud", CLOUD_TOPIC, "--camera-info", LEFT_INFO, RIGHT_INFO]
    assert main([*args, "--method", f"sgbm={disparity_topic('sgbm')}", "--out", str(out)]) == 0
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        assert store.problems() == []
        ((stamp,),) = [store.stamps(sequence)]
        scores = store.frame_scores(sequence, stamp)["sgbm"]
    # The scan through the bag (ROS CameraInfo, /tf_static) is the scene's projected scan.
    scene = list_frames(folder)[0]
    assert scores["all"]["n"] == pytest.approx(int((scene.gt > 0).sum()), abs=3)
    # SGBM on a real KITTI frame (holes interpolated, a car at 2.4 m): 4.3 px, d1 20 %
    assert scores["all"]["mae"] < 6.0
    assert scores["all"]["d1"] < 30.0
    assert scores["0-10m"]["n"] > 0


def test_demo_shows_robot_mode(tmp_path: Path, capsys: Any) -> None:
    assert main(["demo", "--out", str(tmp_path / "demo")]) == 0
    text = capsys.readouterr().out
    assert "robot mode: the same frames against the simulated LiDAR" in text
    assert "mae [px] LiDAR" in text
    with ResultsStore.open(tmp_path / "demo" / "robot") as store:
        (sequence,) = store.sequences()
        assert len(store.stamps(sequence)) == 25
        assert store.problems() == []
    summary = json.loads((tmp_path / "demo" / "summary.json").read_text())  # as dispeval bag
    assert summary["sequences"][0]["models"]["groups"]
    assert summary["provenance"]["version"]


def test_slices_without_tf_static_and_report_thumbnails(drive: Path, tmp_path: Path) -> None:
    from dispeval_ros.report.data import error_thumbnails

    whole = _run_bag(drive, tmp_path / "whole")
    sliced = _run_bag(drive, tmp_path / "sliced", "--slice", "0.1")  # /tf_static in one only
    assert sliced.keys() == whole.keys()
    for key, scores in whole.items():
        np.testing.assert_array_equal(sliced[key].sums, scores.sums)
    with ResultsStore.open(tmp_path / "sliced") as store:
        thumbnails = error_thumbnails(store, [drive], count=2)
    assert thumbnails is not None
    assert len(thumbnails["frames"]) == 2


def test_bag_without_tf_static_asks_for_the_extrinsic(tmp_path: Path, capsys: Any) -> None:
    frames = synthetic_frames(1, 128, 48, FPS, seed=1, lidar=LidarModel())
    bag = tmp_path / "no_tf"
    methods = [m for m in default_methods(128) if m.name == "sgbm"]
    write_bag(bag, frames, methods=methods)
    # The same bag without /tf_static: copy every other topic.
    from dispeval_ros.io.bags import BagSource, BagWriter

    stripped = tmp_path / "stripped"
    with BagSource(bag) as source, BagWriter(stripped, "rosbag2-mcap") as writer:
        for topic, info in source.topics.items():
            if topic != "/tf_static":
                writer.add_topic(topic, info.msgtype)
        for topic, log_time, msg in source.messages(
            [t for t in source.topics if t != "/tf_static"]
        ):
            writer.write(topic, log_time, msg)
    args = ["bag", str(stripped), "--gt-cloud", CLOUD_TOPIC, "--camera-info", LEFT_INFO, RIGHT_INFO]
    args += ["--method", f"sgbm={disparity_topic('sgbm')}", "--out", str(tmp_path / "out")]
    assert main(args) == 2
    assert "has no /tf_static to take the LiDAR → camera transform from" in capsys.readouterr().err
