"""``dispeval bag`` end to end on real bag files of every format, resume after a kill, bad input."""

from __future__ import annotations

import json
import os
import random
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from bag_support import METHODS, as_ros1, bag_args, database_content

from dispeval_ros import Camera
from dispeval_ros.cli.main import main
from dispeval_ros.core.measures import DEFAULT_MEASURES
from dispeval_ros.io import write_pfm
from dispeval_ros.io.bags import BagSource, BagWriter
from dispeval_ros.io.encoders import camera_info_to_msg, disparity_to_msg, image_to_msg
from dispeval_ros.io.messages import camera_from_infos, disparity_from_msg, image_from_msg, stamp_ns
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import (
    GT_TOPIC,
    LEFT_INFO,
    RIGHT_INFO,
    START_NS,
    disparity_topic,
    synthetic_frames,
    write_bag,
)

FORMATS = ("rosbag2-mcap", "rosbag2-sqlite3", "mcap", "ros1")


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same synthetic drive (6 frames, 256×96) in every bag format."""
    root = tmp_path_factory.mktemp("bags")
    frames = list(synthetic_frames(6, 256, 96, 10.0, seed=1))
    paths = {
        "rosbag2-mcap": root / "drive_mcap",
        "rosbag2-sqlite3": root / "drive_sqlite",
        "mcap": root / "drive.mcap",
    }
    for storage, path in paths.items():
        write_bag(path, iter(frames), storage=storage)
    paths["ros1"] = root / "drive.bag"
    as_ros1(paths["rosbag2-sqlite3"], paths["ros1"])
    return paths


def read_frames(
    bag: Path,
) -> tuple[dict[int, np.ndarray], dict[tuple[str, int], np.ndarray], Camera]:
    """GT and every method's disparity by stamp, straight from the bag."""
    gts: dict[int, np.ndarray] = {}
    estimates: dict[tuple[str, int], np.ndarray] = {}
    infos = {}
    topics = [GT_TOPIC, LEFT_INFO, RIGHT_INFO, *(disparity_topic(m) for m in METHODS)]
    with BagSource(bag) as source:
        for topic, _, msg in source.messages(topics):
            if topic == GT_TOPIC:
                gts[stamp_ns(msg.header)] = image_from_msg(msg).array
            elif topic in (LEFT_INFO, RIGHT_INFO):
                infos[topic] = msg
            else:
                estimates[topic.split("/")[2], stamp_ns(msg.header)] = disparity_from_msg(
                    msg
                ).disparity
    return gts, estimates, camera_from_infos(infos[LEFT_INFO], infos[RIGHT_INFO])


@pytest.mark.parametrize("fmt", FORMATS)
def test_bag_gives_exactly_the_scores_of_eval(
    fmt: str, bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # every measure, quantiles included (bag leaves them out by default: not summable)
    assert main(bag_args(bags[fmt], tmp_path / "out", "--measures", *DEFAULT_MEASURES)) == 0
    capsys.readouterr()
    gts, estimates, camera = read_frames(bags[fmt])
    with ResultsStore.open(tmp_path / "out") as store:
        (sequence,) = store.sequences()
        assert store.stamps(sequence) == sorted(gts)
        counts = store.match_counts(sequence)
        assert {
            m: (c.matched, c.unmatched, c.dropped, c.failed) for m, c in counts.items()
        } == dict.fromkeys(METHODS, (6, 0, 0, 0))
        for stamp in sorted(gts)[::2]:
            write_pfm(tmp_path / "gt.pfm", gts[stamp])
            from_bag = store.frame_scores(sequence, stamp)
            for method in METHODS:
                # A DisparityImage's 0 inside [min, max] is valid, a file's 0 missing: written
                # as the smallest normal float32, it scores the same (|tiny − D| = D in float64).
                estimate = estimates[method, stamp]
                tiny = np.finfo(np.float32).tiny
                write_pfm(tmp_path / "est.pfm", np.where(estimate == 0, tiny, estimate))
                code = main(
                    [
                        "eval",
                        "--gt",
                        str(tmp_path / "gt.pfm"),
                        "--est",
                        str(tmp_path / "est.pfm"),
                        "--focal",
                        repr(camera.f),
                        "--baseline",
                        repr(camera.baseline),
                        "--json",
                    ]
                )
                assert code == 0
                from_files = json.loads(capsys.readouterr().out)["frames"][0]["criteria"]
                for criterion, values in from_files.items():
                    for measure, value in values.items():
                        stored = from_bag[method][criterion][measure]
                        if value is None:
                            assert np.isnan(stored), (method, criterion, measure)
                        else:
                            assert stored == value, (fmt, stamp, method, criterion, measure)


def test_bag_summary_and_exports(
    bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert main(bag_args(bags["rosbag2-mcap"], out, "--json")) == 0
    document = json.loads(capsys.readouterr().out)
    (sequence,) = document["sequences"]
    assert sequence["common_frames"] == 6
    assert set(sequence["models"]["groups"]) == set(METHODS)
    assert sequence["models"]["interpretation"]
    assert json.loads((out / "summary.json").read_text()) == document
    header = (out / "frames.csv").read_text().splitlines()[0].split(",")
    assert header[:5] == ["sequence", "stamp", "method", "criterion", "n"]
    assert main(bag_args(bags["rosbag2-mcap"], out)) == 2  # results exist: refuse without --resume
    assert "--resume" in capsys.readouterr().err


def test_jobs_give_the_same_database(
    bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(bag_args(bags["rosbag2-sqlite3"], tmp_path / "one", "--slice", "0.2")) == 0
    assert (
        main(bag_args(bags["rosbag2-sqlite3"], tmp_path / "two", "--slice", "0.2", "--jobs", "2"))
        == 0
    )
    capsys.readouterr()
    assert database_content(tmp_path / "one") == database_content(tmp_path / "two")


def group_alive(pgid: int) -> bool:
    """Whether any process of a process group is still running (zombies do not count)."""
    for status in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = status.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            return True
    return False


def units_stored(database: Path) -> int | None:
    """How many units a run's database holds now (None: not readable at this moment)."""
    try:
        connection = sqlite3.connect(f"file:{database}?mode=ro", uri=True, timeout=0.2)
        try:
            return int(connection.execute("SELECT COUNT(*) FROM units").fetchone()[0])
        finally:
            connection.close()
    except sqlite3.Error:  # not created yet, or the writer holds it mid-commit
        return None


def start_interruptible(command: list[str]) -> subprocess.Popen[bytes]:
    """Start ``command`` in its own session with Ctrl-C at its default.

    A program inherits an ignored SIGINT (pytest started in the background with ``&`` has
    one) and rightly keeps ignoring it; the child gets the default whatever started pytest.
    """
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return subprocess.Popen(
            command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True
        )
    finally:
        signal.signal(signal.SIGINT, previous)


@pytest.mark.parametrize(
    ("how", "jobs"),
    [("SIGKILL", "1"), ("SIGKILL", "2"), ("SIGTERM", "2"), ("SIGINT", "2")],
)
def test_killed_run_resumes_to_the_same_database(how: str, jobs: str, tmp_path: Path) -> None:
    """Killed, terminated or interrupted at a random moment: --resume gives the same database,
    and no process of the run is left (pool workers end with their driver).

    The signal goes to a driver frozen (SIGSTOP) while it has stored at least one unit and not
    all: it is then mid-run whatever the load, so a clean stop must say so (exit 130/143). A
    driver frozen with every unit stored may be past its last check (exporting, or exiting),
    where exit 0 is right: that attempt starts over.
    """
    bag = tmp_path / "long"
    write_bag(bag, synthetic_frames(24, 192, 64, 10.0, seed=2), storage="rosbag2-sqlite3")
    command = [sys.executable, "-m", "dispeval_ros", *bag_args(bag, tmp_path / "killed")]
    command += ["--slice", "0.1", "--jobs", jobs]
    reference = [sys.executable, "-m", "dispeval_ros", *bag_args(bag, tmp_path / "whole")]
    subprocess.run([*reference, "--slice", "0.1"], check=True, capture_output=True)
    total = units_stored(tmp_path / "whole" / "results.sqlite")
    assert total is not None
    assert total > 2
    rng = random.Random(7)
    database = tmp_path / "killed" / "results.sqlite"
    for _attempt in range(20):
        process = start_interruptible(command)
        while process.poll() is None and not units_stored(database):
            time.sleep(0.01)
        time.sleep(rng.uniform(0.0, 0.3))
        if process.poll() is None:
            os.kill(process.pid, signal.SIGSTOP)
            stored = units_stored(database) if process.poll() is None else None
            if stored is not None and 0 < stored < total:
                os.kill(process.pid, getattr(signal, how))  # pending until it runs again
                os.kill(process.pid, signal.SIGCONT)
                _, err = process.communicate(timeout=60)
                break
            os.kill(process.pid, signal.SIGCONT)
        process.communicate(timeout=60)  # finished, or nearly: start over with a fresh folder
        for file in (tmp_path / "killed").iterdir():
            file.unlink()
    else:
        pytest.fail("the run was never caught with some of its units stored and not all")
    deadline = time.monotonic() + 10
    while group_alive(process.pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not group_alive(process.pid), "a process of the killed run is still running"
    if how != "SIGKILL":  # a clean stop: one line, no traceback
        text = err.decode(errors="replace")
        # exit status 128 + n, or (seen once in 16 loaded SIGINT runs, the line printed, no
        # traceback) death by the signal itself: a shell's $? is 128 + n for both
        number = getattr(signal, how)
        assert process.returncode in (128 + number, -number), text
        assert text.count("\n") == 1, text
        assert "Traceback" not in text
    resumed = subprocess.run([*command, "--resume"], capture_output=True, text=True, check=False)
    assert resumed.returncode == 0, resumed.stderr
    assert database_content(tmp_path / "killed") == database_content(tmp_path / "whole")


# -- bad input -------------------------------------------------------------------------------


def write_custom_bag(
    path: Path,
    *,
    gt_encoding: str = "32FC1",
    method_width: int = 64,
    baseline: float = 0.5,
    disparity_cameras: tuple[tuple[float, float], ...] = ((100.0, 1.0),) * 3,
    repeat_first: bool = False,
) -> None:
    """A hand-made bag: 3 frames, one method, chosen defects (f, t of each DisparityImage)."""
    camera = Camera(f=100.0, baseline=1.0)
    with BagWriter(path, "rosbag2-mcap") as bag:
        typestore = bag.typestore
        bag.add_topic(GT_TOPIC, "sensor_msgs/msg/Image")
        bag.add_topic(LEFT_INFO, "sensor_msgs/msg/CameraInfo")
        bag.add_topic(RIGHT_INFO, "sensor_msgs/msg/CameraInfo")
        bag.add_topic("/m/disparity", "stereo_msgs/msg/DisparityImage")
        for i in range(3):
            stamp = START_NS + i * 100_000_000
            gt = np.full((48, 64), 10.0, np.float32)
            if gt_encoding == "rgb8":
                gt_msg = image_to_msg(
                    typestore, np.zeros((48, 64, 3), np.uint8), stamp, "l", "rgb8"
                )
            else:
                gt_msg = image_to_msg(typestore, gt, stamp, "l", gt_encoding)
            bag.write(
                LEFT_INFO, stamp, camera_info_to_msg(typestore, camera, 64, 48, stamp, "l", False)
            )
            right = camera_info_to_msg(
                typestore, Camera(f=100.0, baseline=1.0), 64, 48, stamp, "r", True
            )
            if baseline == 0.0:
                right.p[3] = 0.0
            bag.write(RIGHT_INFO, stamp, right)
            bag.write(GT_TOPIC, stamp, gt_msg)
            estimate = np.full((48, method_width), 10.5, np.float32)
            f, t = disparity_cameras[i]
            disparity = disparity_to_msg(typestore, estimate, stamp, "l", f, t, 0.0, 63.0)
            bag.write("/m/disparity", stamp + 1, disparity)
            if repeat_first and i == 0:  # the same frame recorded twice
                bag.write(GT_TOPIC, stamp + 2, gt_msg)
                bag.write("/m/disparity", stamp + 3, disparity)


def run_custom(
    path: Path,
    out: Path,
    capsys: pytest.CaptureFixture[str],
    camera_info: bool = True,
    extra: tuple[str, ...] = (),
) -> tuple[int, str, str]:
    infos = ["--camera-info", LEFT_INFO, RIGHT_INFO] if camera_info else []
    code = main(
        [
            "bag",
            str(path),
            "--gt",
            GT_TOPIC,
            "--method",
            "m=/m/disparity",
            *infos,
            "--out",
            str(out),
            "--quiet",
            *extra,
        ]
    )
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_missing_topic_lists_what_exists(
    bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(
        [
            "bag",
            str(bags["mcap"]),
            "--gt",
            "/nope",
            "--method",
            "x=/stereo/sgbm/disparity",
            "--out",
            str(tmp_path / "o"),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1
    assert "/nope" in err
    assert f"{GT_TOPIC} (sensor_msgs/msg/Image" in err
    assert "stereo_msgs/msg/DisparityImage" in err


@pytest.mark.parametrize(
    ("defect", "expected", "scored"),
    [
        ({"method_width": 60}, "60", 0),
        ({"gt_encoding": "rgb8"}, "rgb8", 0),
        ({"baseline": 0.0}, "baseline", 3),  # pixel measures need no camera
    ],
    ids=["size-mismatch", "unknown-encoding", "zero-baseline"],
)
def test_per_frame_problems_are_recorded_not_fatal(
    defect: dict, expected: str, scored: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    write_custom_bag(tmp_path / "bag", **defect)
    code, out, _ = run_custom(tmp_path / "bag", tmp_path / "out", capsys)
    assert code == 0
    assert "problem(s) recorded" in out
    with ResultsStore.open(tmp_path / "out") as store:
        problems = store.problems()
        assert len(problems) == 3
        assert all(expected in p.message and "\n" not in p.message for p in problems)
        counts = store.match_counts(store.sequences()[0])["m"]
        assert (counts.matched, counts.failed) == (scored, 3 - scored)


def test_good_custom_bag_scores(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_custom_bag(tmp_path / "bag")
    code, _, _ = run_custom(tmp_path / "bag", tmp_path / "out", capsys)
    assert code == 0
    with ResultsStore.open(tmp_path / "out") as store:
        sequence = store.sequences()[0]
        scores = store.sequence_scores(sequence)["m"]
        assert scores["all"]["mae"] == pytest.approx(0.5)
        assert scores["all"]["n"] == 3 * 48 * 64
        assert store.problems() == []


@pytest.mark.parametrize("fmt", ["rosbag2-sqlite3", "mcap"])
def test_truncated_bag_is_a_clear_error_and_keeps_results(
    fmt: str, bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = bags[fmt]
    damaged = tmp_path / "damaged"
    if fmt == "mcap":
        damaged = tmp_path / "damaged.mcap"
        data = source.read_bytes()
        damaged.write_bytes(data[: len(data) * 2 // 3])
    else:
        damaged.mkdir()
        for file in source.iterdir():
            data = file.read_bytes()
            (damaged / file.name).write_bytes(
                data if file.suffix == ".yaml" else data[: len(data) // 2]
            )
    code = main(bag_args(damaged, tmp_path / "out"))
    captured = capsys.readouterr()
    if code == 2:  # refused at opening: one line, naming the bag
        assert captured.err.count("\n") == 1
        assert "damaged" in captured.err
    else:  # read up to the damage: what came before is scored, the damage is a recorded problem
        assert code == 0
        with ResultsStore.open(tmp_path / "out") as store:
            assert any("reading stopped" in p.message for p in store.problems())
            assert store.stamps(store.sequences()[0])


def test_a_disparity_image_without_a_camera_keeps_its_pixel_measures(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """t = 0 or NaN f (no CameraInfo topics): pixel measures scored, depth ones nan and said."""
    cameras = ((100.0, 1.0), (100.0, 0.0), (float("nan"), 1.0))
    write_custom_bag(tmp_path / "bag", disparity_cameras=cameras)
    code, out, _ = run_custom(tmp_path / "bag", tmp_path / "out", capsys, camera_info=False)
    assert code == 0, out
    assert (tmp_path / "out" / "summary.json").is_file()
    with ResultsStore.open(tmp_path / "out") as store:
        sequence = store.sequences()[0]
        counts = store.match_counts(sequence)["m"]
        assert (counts.matched, counts.failed) == (3, 0)
        messages = [p.message for p in store.problems()]
        assert len(messages) == 2
        assert all("depth measures not scored" in m for m in messages), messages
        assert any("f = 100, t = 0" in m for m in messages), messages
        assert any("f = nan, t = 1" in m for m in messages), messages
        stamps = store.stamps(sequence)
        metric, *without = (store.frame_scores(sequence, s)["m"]["all"] for s in stamps)
        assert np.isfinite(metric["sze"])
        for scores in without:
            assert np.isnan(scores["sze"])
            assert scores["mae"] == metric["mae"]
        assert not store.sequence_scores(sequence)["m"].relative


def test_a_negative_t_is_its_magnitude_said_once_per_topic(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """t < 0 (no CameraInfo topics): every frame scored as with |t|; one warning line."""
    results = {}
    for sign in (-1.0, 1.0):
        bag, out = tmp_path / f"bag{sign:+}", tmp_path / f"out{sign:+}"
        write_custom_bag(bag, disparity_cameras=((100.0, sign),) * 3)
        code, _, err = run_custom(bag, out, capsys, camera_info=False, extra=("--slice", "0.1"))
        assert code == 0
        said = [line for line in err.splitlines() if "t = -1 < 0" in line]
        assert len(said) == (1 if sign < 0 else 0), err
        with ResultsStore.open(out) as store:
            sequence = store.sequences()[0]
            counts = store.match_counts(sequence)["m"]
            assert (counts.matched, counts.failed) == (3, 0)
            results[sign] = store.sequence_scores(sequence)["m"].sums
    np.testing.assert_array_equal(results[-1.0], results[1.0])


def test_a_frame_recorded_twice_is_scored_once_and_resumes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    write_custom_bag(tmp_path / "bag", repeat_first=True)
    code, out, _ = run_custom(tmp_path / "bag", tmp_path / "out", capsys)
    assert code == 0, out
    with ResultsStore.open(tmp_path / "out") as store:
        sequence = store.sequences()[0]
        assert len(store.stamps(sequence)) == 3
        counts = store.match_counts(sequence)["m"]
        assert (counts.matched, counts.unmatched) == (3, 1)  # the second copy's estimate
        (problem,) = store.problems()
        assert "more than once" in problem.message
    code, _, _ = run_custom(tmp_path / "bag", tmp_path / "out", capsys)  # results exist
    assert code == 2
    code, out, _ = run_custom(tmp_path / "bag", tmp_path / "out", capsys, extra=("--resume",))
    assert code == 0, out
