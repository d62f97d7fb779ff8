"""``dispeval bag --egomotion`` with LiDAR ground truth: the drift between scans, per pair.

make-bag's synthetic drive with its simulated LiDAR records each frame's scan on
``/lidar/points``, the drive's exact motion on ``/tf`` and the mounts on ``/tf_static``. The
drift pooled from the bag equals a plain numpy re-computation from the definition
(test/drift_support.py) on the scans the bag's frames were projected to, the maps the bag was
made of and the drive's exact motion (written from the rig's optical centres, not read from
/tf); a constant 1 px bias drifts exactly what the true disparity drifts; many units give the
rows of one; a bag without LiDAR GT gives no drift and no error; a database written before
the drift table reads as "not recorded". The drift of the true disparity is not 0 on this
drive: its traffic and its far wall move with the camera (the static-world assumption does
not hold there), so the tests compare methods, not a method with 0.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from bag_support import as_written_before, drive_motion_lookup
from drift_support import THRESHOLDS, numpy_drift

from dispeval_ros.cli.main import main
from dispeval_ros.core.camera import Camera
from dispeval_ros.core.egomotion import PinholeCamera
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import (
    CAMERA_FRAME,
    CLOUD_TOPIC,
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
from dispeval_ros.stream.core import CoreConfig, EvaluationCore
from dispeval_ros.stream.summarizer import SummarizerConfig, SummarizerCore
from dispeval_ros.stream.vectors import (
    DRIFT_KEY_PREFIX,
    drift_from_status,
    read_pairs,
    result_statuses,
    scores_from_status,
)
from dispeval_ros.testbed.lidar import LidarModel
from dispeval_ros.testbed.methods import default_methods
from dispeval_ros.testbed.presets import driving_setup

FRAMES, WIDTH, HEIGHT, SEED = 5, 620, 188, 4
METHODS = ("truth", "biased", "noisy")
CRITERIA = ("all", "depth")
"""``all`` and the LiDAR depth ranges (0–10, 10–30, 30+ m): the rows numpy_drift gives."""


def estimate_of(method: str, gt: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The true disparity, the same plus 1 px, or plus 0.5 px of noise drawn anew per frame."""
    noise = rng.normal(0.0, 0.5, gt.shape) if method == "noisy" else 0.0
    return (gt + (1.0 if method == "biased" else 0.0) + noise).astype(np.float32)


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The drive with its LiDAR and the methods' maps (saved as ROOT/METHOD/NNNNNN.npy)."""
    root = tmp_path_factory.mktemp("driftbag")
    frames = list(synthetic_frames(FRAMES, WIDTH, HEIGHT, 10.0, seed=SEED, lidar=LidarModel()))
    rng = np.random.default_rng(3)
    for method in METHODS:
        (root / method).mkdir()
        for index, frame in enumerate(frames):
            estimate = estimate_of(method, np.asarray(frame.gt, dtype=np.float32), rng)
            np.save(root / method / f"{index:06d}.npy", estimate)
    write_bag(
        root / "drive", iter(frames), storage="rosbag2-sqlite3",
        methods=default_methods(WIDTH)[:1],
        estimates=[estimates_from(m, root / m) for m in METHODS],
    )  # fmt: skip
    return root / "drive"


def command(bag: Path, out: Path, *extra: str, gt: tuple[str, str] = ("--gt-cloud", CLOUD_TOPIC)):
    return [
        "bag", str(bag), *gt, *(i for m in METHODS for i in ("--method", f"{m}={disparity_topic(m)}")),
        "--camera-info", LEFT_INFO, RIGHT_INFO, "--left-image", LEFT_IMAGE,
        "--right-image", RIGHT_IMAGE, "--egomotion", "--criteria", *CRITERIA, "--out", str(out),
        "--quiet", *extra,
    ]  # fmt: skip


def drift_rows(folder: Path) -> list[tuple]:
    connection = sqlite3.connect(folder / "results.sqlite")
    found = connection.execute("SELECT * FROM drift_pairs ORDER BY stamp, method").fetchall()
    connection.close()
    return found


def config() -> CoreConfig:
    return CoreConfig(
        methods={m: disparity_topic(m) for m in METHODS}, gt_topic=CLOUD_TOPIC, gt_kind="pointcloud",
        left_info_topic=LEFT_INFO, right_info_topic=RIGHT_INFO, left_image_topic=LEFT_IMAGE,
        right_image_topic=RIGHT_IMAGE, egomotion=True, criteria=CRITERIA,
    )  # fmt: skip


def scans_through_the_core(bag: Path) -> tuple[list[np.ndarray], list]:
    """Each frame's projected scan (the GT its frames were scored on) and every result."""
    core = EvaluationCore(config())
    assert core.pairs is not None
    assert core.pairs.drift is not None
    core.pairs.motion = drive_motion_lookup(WIDTH, HEIGHT, SEED)  # not the bag's /tf
    scans, results = [], []
    topics = [t for t in config().topics if not t.startswith("/tf") or t == "/tf_static"]
    with BagSource(bag) as source:
        for topic, log_ns, msg in source.messages(topics):
            for frame_set in core.push(topic, msg, log_ns):
                result = core.score(frame_set)
                assert result.pair_input is not None
                assert result.pair_input.reference is not None
                scans.append(result.pair_input.reference.gt)
                results.append(core.pair(result))
    return scans, results


def numpy_pooled(root: Path, scans: list[np.ndarray], method: str, policy: str) -> np.ndarray:
    """The method's drift over the drive's pairs, in numpy, under the exact motion."""
    world, rig = driving_setup(WIDTH, HEIGHT, 10.0, SEED)
    del world
    camera = PinholeCamera(Camera(rig.f, rig.baseline), rig.cx, rig.cy)
    lookup = drive_motion_lookup(WIDTH, HEIGHT, SEED)
    maps = [np.load(root / method / f"{i:06d}.npy") for i in range(FRAMES)]
    from dispeval_ros.offline.make_bag import START_NS

    period = 100_000_000  # 10 Hz
    total = []
    for t in range(FRAMES - 1):
        motion = lookup(CAMERA_FRAME, START_NS + t * period, START_NS + (t + 1) * period)
        pair = numpy_drift((scans[t], scans[t + 1]), (maps[t], maps[t + 1]), motion, camera, policy)
        total.append(pair)
    return np.sum(total, axis=0)


@pytest.mark.parametrize("policy", ["interpolate", "ignore"])
def test_the_drift_from_the_bag_equals_numpy_on_its_scans_and_the_exact_motion(
    drive: Path, tmp_path: Path, policy: str
) -> None:
    out = tmp_path / "out"
    assert main(command(drive, out, "--missing", policy)) == 0
    scans, _ = scans_through_the_core(drive)
    assert len(scans) == FRAMES
    with ResultsStore.open(out) as store:
        stored = store.drift_pairs("drive")
        assert stored is not None
        assert not [p for p in store.problems() if "drift" in p.message or "ego" in p.message]
    summary = json.loads((out / "summary.json").read_text())["sequences"][0]["lidar_drift"]
    assert summary["options"] == {
        "missing": policy, "visibility": "7,0.1", "thresholds": list(THRESHOLDS),
    }  # fmt: skip
    assert summary["label"].endswith("not accuracy")
    for method in METHODS:
        pairs, pooled = stored[method]
        assert pairs == FRAMES - 1
        assert pooled.criteria[0] == "all"
        assert len(pooled.criteria) == 4
        expected = numpy_pooled(drive.parent, scans, method, policy)
        np.testing.assert_allclose(pooled.sums, expected, rtol=1e-6, atol=1e-6)
        entry = summary["methods"][method]
        assert entry["pairs"] == FRAMES - 1
        assert list(entry["sums"]["drift:all"].values()) == pytest.approx(pooled.sums[0].tolist())
        one = entry["criteria"]["drift:all"]
        assert one["mean"] == pytest.approx(expected[0, 7] / expected[0, 1])
        assert one["counted"] == pytest.approx(100 * expected[0, 1] / expected[0, 0])
    truth, biased, noisy = (stored[m][1] for m in METHODS)
    # A constant 1 px bias drifts what the true disparity drifts: every column but Σ error.
    np.testing.assert_allclose(np.delete(biased.sums, 10, axis=1),
                               np.delete(truth.sums, 10, axis=1), rtol=1e-5, atol=1e-3)  # fmt: skip
    counted = biased.sums[:, 1]
    np.testing.assert_allclose(biased.sums[:, 10] - truth.sums[:, 10], counted, rtol=1e-6)
    # Per-frame noise drifts: most points that the true disparity keeps below 0.5 px exceed it.
    assert noisy.summary("all")["bad_0.5"] > truth.summary("all")["bad_0.5"] + 30


def test_many_units_give_the_drift_rows_of_one(drive: Path, tmp_path: Path) -> None:
    many, one = tmp_path / "many", tmp_path / "one"
    assert main(command(drive, many, "--slice", "0.15")) == 0
    assert main(command(drive, one, "--slice", "100")) == 0
    with ResultsStore.open(many) as store:
        assert len(store.done_units("drive")) >= 3
    rows = drift_rows(many)
    assert len(rows) == (FRAMES - 1) * len(METHODS)
    assert rows == drift_rows(one)
    summaries = [json.loads((f / "summary.json").read_text()) for f in (many, one)]
    drifts = [s["sequences"][0]["lidar_drift"] for s in summaries]
    assert drifts[0] == drifts[1]


def test_the_bag_tables_show_the_drift_as_summary_json_has_it(
    drive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    args = [a for a in command(drive, out) if a != "--quiet"]
    assert main(args) == 0
    text = capsys.readouterr().out
    text = text[text.index("LiDAR drift between scans") :]
    assert "not accuracy" in " ".join(text.split())
    entry = json.loads((out / "summary.json").read_text())["sequences"][0]["lidar_drift"]
    for method in METHODS:
        line = next(x for x in text.splitlines() if x.split()[:2] == ["drift:all", method])
        cells = line.split()[2:]
        one = entry["methods"][method]["criteria"]["drift:all"]
        assert int(cells[0]) == FRAMES - 1
        assert int(cells[1]) == one["n"]
        assert float(cells[3]) == pytest.approx(one["mean"], rel=1e-3)


def test_a_bag_without_lidar_gt_gives_no_drift_and_no_error(drive: Path, tmp_path: Path) -> None:
    out = tmp_path / "dense"
    assert main(command(drive, out, gt=("--gt", GT_TOPIC))) == 0
    assert drift_rows(out) == []
    with ResultsStore.open(out) as store:
        assert store.drift_pairs("drive") == {}
        motion = store.motion_pairs("drive")
        assert motion is not None
        assert motion["truth"][0] == FRAMES - 1
    sequence = json.loads((out / "summary.json").read_text())["sequences"][0]
    assert sequence["lidar_drift"] is None
    assert sequence["egomotion"]["truth"]["pairs"] == FRAMES - 1


def test_a_database_written_before_the_drift_table_reads_as_not_recorded(
    drive: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    assert main(command(drive, out, "--slice", "100")) == 0
    assert main(["report", str(out)]) == 0
    old = tmp_path / "old"
    as_written_before(out, old, "drift_pairs")
    with ResultsStore.open(old) as store:
        assert store.drift_pairs("drive") is None
        assert store.motion_pairs("drive") is not None
    assert main(["report", str(old)]) == 0


def test_the_scores_statuses_carry_each_pairs_drift_and_a_summarizer_stores_it(
    drive: Path, tmp_path: Path
) -> None:
    """Live shares the stream core: a frame's status has the drift keys, read back exactly,
    and the summarizers' core stores them as ``dispeval bag`` does."""
    _, results = scans_through_the_core(drive)
    topics = {m: disparity_topic(m) for m in METHODS}
    core = SummarizerCore(SummarizerConfig(tmp_path / "live", every_n=2), {"run": "live"})
    seen = 0
    for result in results:
        here = {p.method: p.drift for p in result.motion_pairs if p.stamp == result.stamp}
        scores, pairs, motion, drifts = {}, {}, {}, {}
        for status in result_statuses(result, topics):
            scores[status.name] = scores_from_status(status.values)
            read_pairs(status, pairs, motion, drift=drifts)
            drift = drift_from_status(status.values)
            if status.name not in here:
                assert drift is None
                continue
            expected = here[status.name]
            assert drift is not None
            assert expected is not None
            assert drift.criteria == expected.criteria
            assert drift.options == expected.options
            np.testing.assert_array_equal(drift.sums, expected.sums)
            keys = dict(status.values)
            value = keys[f"{DRIFT_KEY_PREFIX}drift:all/mean"]
            assert float(value) == expected.summary("all")["mean"]
            seen += 1
        core.add(result.stamp, scores, None, None, motion, drift=drifts)
    assert seen == (FRAMES - 1) * len(METHODS)
    assert core.finish() is not None
    with ResultsStore.open(tmp_path / "live") as store:
        stored = store.drift_pairs(store.sequences()[0])
    assert stored is not None
    for method in METHODS:
        parts = [p.drift for r in results for p in r.motion_pairs if p.method == method]
        assert stored[method][0] == len(parts) == FRAMES - 1
        np.testing.assert_array_equal(stored[method][1].sums, np.sum([p.sums for p in parts], 0))


def test_a_make_scene_drive_drifts_in_its_bag_as_eval_scores_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The same drive both ways: ``eval --scene --gt-source scan`` on make-scene's KITTI raw
    drive, ``dispeval bag --gt-cloud`` on make-bag's bag of it (the scans as PointCloud2, the
    oxts as /tf, the maps as DisparityImages): the same projected scans, motion and maps give
    the same drift sums, to rounding."""
    assert main(["make-scene", str(tmp_path / "sc"), "--frames", "4", "--no-traffic"]) == 0
    scene = tmp_path / "sc" / "2000_01_01" / "2000_01_01_drive_0001_sync"
    ests = {"mine": tmp_path / "sc" / "estimates" / "sgbm", "true": scene / "gt" / "disp_occ_0"}
    est_args = [i for name, folder in ests.items() for i in ("--est", f"{name}={folder}")]
    assert main(["make-bag", str(tmp_path / "bag"), "--scene", str(scene), *est_args]) == 0
    quick = ["--criteria", *CRITERIA, "--gt-free-criteria", "all", "--egomotion"]
    capsys.readouterr()
    assert main(["eval", "--scene", str(scene), "--gt-source", "scan", *est_args, *quick,
                 "--json"]) == 0  # fmt: skip
    scored = json.loads(capsys.readouterr().out)["egomotion"]["lidar_drift"]
    topics = [i for name in ests for i in ("--method", f"{name}=/stereo/{name}/disparity")]
    out = tmp_path / "res"
    assert main([
        "bag", str(tmp_path / "bag"), "--gt-cloud", CLOUD_TOPIC, "--camera-info", LEFT_INFO,
        RIGHT_INFO, "--left-image", LEFT_IMAGE, "--right-image", RIGHT_IMAGE, *topics,
        "--tolerance", "20", *quick, "--out", str(out), "--quiet",
    ]) == 0  # fmt: skip
    bagged = json.loads((out / "summary.json").read_text())["sequences"][0]["lidar_drift"]
    assert bagged["options"] == scored["options"]
    for name in ests:
        got, expected = bagged["methods"][name]["sums"], scored["methods"][name]["sums"]
        assert list(got) == list(expected)
        assert len(got) == 4
        for criterion, sums in expected.items():
            assert got[criterion] == pytest.approx(sums, rel=1e-9, abs=1e-6), criterion
        assert got["drift:all"]["n_drift"] > 0.8 * got["drift:all"]["n"]
    true = bagged["methods"]["true"]["criteria"]["drift:all"]
    assert true["mean"] < 0.05  # a static world: the true disparity hardly drifts


@pytest.mark.data
def test_the_readme_states_the_shared_drives_drift_from_its_bag(
    shared_data: Path, tmp_path: Path
) -> None:
    """The README's numbers of ``dispeval bag --egomotion`` on make-bag's bag of the shared
    KITTI raw drive, by the command it shows."""
    from test_readme import README

    scene = shared_data / "kitti-raw-drive-0048" / "2011_09_26" / "2011_09_26_drive_0048_sync"
    assert main(["make-bag", str(tmp_path / "drive"), "--scene", str(scene)]) == 0
    out = tmp_path / "results"
    assert main([
        "bag", str(tmp_path / "drive"), "--gt-cloud", CLOUD_TOPIC, "--camera-info", LEFT_INFO,
        RIGHT_INFO, "--left-image", LEFT_IMAGE, "--right-image", RIGHT_IMAGE,
        "--method", "sgbm=/stereo/sgbm/disparity", "--method", "bm_fast=/stereo/bm_fast/disparity",
        "--tolerance", "20", "--egomotion", "--criteria", "all", "depth", "--out", str(out),
        "--quiet",
    ]) == 0  # fmt: skip
    entry = json.loads((out / "summary.json").read_text())["sequences"][0]["lidar_drift"]
    sgbm, bm = (entry["methods"][m]["criteria"]["drift:all"] for m in ("sgbm", "bm_fast"))
    assert entry["methods"]["sgbm"]["pairs"] == entry["methods"]["bm_fast"]["pairs"] == 9
    assert sgbm["n_drift"] == bm["n_drift"]
    text = " ".join(README.read_text(encoding="utf-8").split())
    expected = (
        f"give `drift:all` SGBM {sgbm['mean']:.2f} px mean, {sgbm['bad_1']:.1f} % above 1 px, "
        f"BM {bm['mean']:.2f} px, {bm['bad_1']:.1f} %, over {int(sgbm['n_drift'])} of the "
        f"{int(sgbm['n'])} points ({sgbm['counted']:.1f} %)"
    )
    assert expected in text


def test_a_pair_whose_drift_fails_keeps_its_residual_and_says_why_in_one_line() -> None:
    """Scans of two sizes (a camera whose resolution changed): the drift is one problem line,
    the residual of the pair is scored and kept."""
    from dispeval_ros.core.egomotion import EgoMotionOptions
    from dispeval_ros.core.evaluator import Evaluator
    from dispeval_ros.core.lidar_drift import DriftOptions
    from dispeval_ros.stream.pairs import PairInput, PairStage

    camera = Camera(100.0, 0.5)
    stage = PairStage(Evaluator(), None, egomotion=EgoMotionOptions(), drift=DriftOptions())
    stage.motion = lambda frame, t0, t1: np.eye(4)
    pinhole = PinholeCamera(camera, 16.0, 12.0)
    estimate = np.full((24, 32), 10.0, np.float32)
    outcomes = []
    for index, shape in enumerate([(24, 32), (20, 32)]):
        scan = np.zeros(shape, np.float32)
        scan[::3, ::3] = 10.0
        reference = Evaluator().reference(scan, camera)
        inputs = {"m": stage.prepare(estimate, None, 0.0)}
        frame = PairInput(index * 100_000_000, reference, inputs, None, pinhole, "cam")
        outcomes.append(stage.add(frame))
    outcomes.append(stage.finish())
    pairs = [p for o in outcomes for p in o.motion]
    problems = [text for o in outcomes for _, text in o.problems]
    assert len(pairs) == 1
    assert pairs[0].drift is None
    assert pairs[0].sums.summary("all")["n_residual"] > 0
    assert len(problems) == 1
    assert problems[0].startswith("m: no LiDAR drift 0 → 100000000: the scan at t + k is 32×20")
