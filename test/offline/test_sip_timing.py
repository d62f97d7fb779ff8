"""Real producer, real recorder: every frame of the stereo_image_proc bags counted once.

The shared bags (``stereo-image-proc/``, see its README) hold the output of the real
``stereo_image_proc`` disparity nodelet (BM and SGBM) recorded with ``rosbag``: header stamps
in 2020, log time years later. Re-timed copies are made here: stamps moved 10 years (now
*after* the log time), the frames spread over 12 s of log time, and one where SGBM is logged
1.5 s after its frame. Whatever the slicing and executor, each method must score every frame,
and the counts must add up to what the bag holds (read here with rosbags, not the project).
"""

from __future__ import annotations

import dataclasses
import functools
from collections import Counter
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

from dispeval_ros.cli.main import main
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.bag_eval import evaluate_bags, sequence_names
from dispeval_ros.stream.core import CoreConfig

GT = "/stereo/ground_truth/disparity"
METHODS = {"bm": "/stereo_bm/disparity", "sgbm": "/stereo_sgbm/disparity"}
INFOS = ("/stereo/left/camera_info", "/stereo/right/camera_info")
NOETIC = get_typestore(Stores.ROS1_NOETIC)
SECOND = 1_000_000_000
YEARS_10 = round(10 * 365.25 * 86_400) * SECOND
SPREAD_NS = 12 * SECOND
LATE_NS = 1_500_000_000
BAGS = ("sip_kitti.bag", "sip_mb_doffs0.bag")


@dataclasses.dataclass(frozen=True)
class Recorded:
    """One message of a bag: topic, log time, header stamp, type and the message."""

    topic: str
    log_ns: int
    stamp: int
    msgtype: str
    msg: object


def read(path: Path) -> list[Recorded]:
    """Every message of a ROS 1 bag, deserialised by rosbags, in log-time order."""
    with AnyReader([path], default_typestore=NOETIC) as reader:
        return [
            Recorded(
                conn.topic,
                log_ns,
                msg.header.stamp.sec * SECOND + msg.header.stamp.nanosec,
                conn.msgtype,
                msg,
            )
            for conn, log_ns, raw in reader.messages()
            for msg in [reader.deserialize(raw, conn.msgtype)]
        ]


def restamped(msg: object, stamp: int) -> object:
    """``msg`` with header stamp ``stamp`` (ns)."""
    time = type(msg.header.stamp)(sec=stamp // SECOND, nanosec=stamp % SECOND)  # type: ignore[attr-defined]
    return dataclasses.replace(msg, header=dataclasses.replace(msg.header, stamp=time))  # type: ignore[attr-defined,type-var]


def write_retimed(source: list[Recorded], path: Path, late_topic: str | None = None) -> None:
    """A re-timed copy of ``source``: stamps 10 years later, frame i logged at T0 + i·period
    (+1 ms per message within the frame), the messages of ``late_topic`` 1.5 s later still."""
    stamps = sorted({m.stamp for m in source})
    period = SPREAD_NS // max(1, len(stamps) - 1)
    start = source[0].log_ns
    within: Counter[int] = Counter()
    timed = []
    for message in source:
        frame = stamps.index(message.stamp)
        log_ns = start + frame * period + within[frame] * 1_000_000
        within[frame] += 1
        if message.topic == late_topic:
            log_ns += LATE_NS
        timed.append((log_ns, message))
    with Writer(path) as writer:
        connections = {}
        for log_ns, message in sorted(timed, key=lambda item: item[0]):
            if message.topic not in connections:
                connections[message.topic] = writer.add_connection(
                    message.topic, message.msgtype, typestore=NOETIC
                )
            data = NOETIC.serialize_ros1(
                restamped(message.msg, message.stamp + YEARS_10), message.msgtype
            )
            writer.write(connections[message.topic], log_ns, data)


@pytest.fixture(scope="module")
def bags(shared_data: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The two shared bags and, of each, a spread copy and a copy with SGBM 1.5 s late."""
    root = tmp_path_factory.mktemp("retimed")
    found: dict[str, Path] = {}
    for name in BAGS:
        original = shared_data / "stereo-image-proc" / name
        stem = Path(name).stem
        messages = read(original)
        found[stem] = original
        found[f"{stem}_spread"] = root / f"{stem}_spread.bag"
        found[f"{stem}_late"] = root / f"{stem}_late.bag"
        write_retimed(messages, found[f"{stem}_spread"])
        write_retimed(messages, found[f"{stem}_late"], late_topic=METHODS["sgbm"])
    return found


@dataclasses.dataclass(frozen=True)
class Content:
    """What a bag holds, by rosbags: GT stamps, estimates per method, log time − stamp."""

    gt_stamps: list[int]
    estimates: dict[str, int]
    first_gt_offset: int
    log_span: int


@functools.cache
def content(path: Path) -> Content:
    messages = read(path)
    gt = [m for m in messages if m.topic == GT]
    return Content(
        [m.stamp for m in gt],
        {method: sum(m.topic == topic for m in messages) for method, topic in METHODS.items()},
        gt[0].log_ns - gt[0].stamp,
        messages[-1].log_ns - messages[0].log_ns,
    )


def config(lateness_ms: float = 1000.0) -> CoreConfig:
    """BM and SGBM against the GT, camera from the CameraInfo pair; one criterion, two measures
    (the counts do not depend on what is scored)."""
    return CoreConfig(
        methods=METHODS,
        gt_topic=GT,
        left_info_topic=INFOS[0],
        right_info_topic=INFOS[1],
        criteria=("all",),
        measures=("density", "bmp"),
        lateness_ns=round(lateness_ms * 1e6),
    )


def evaluate(
    paths: list[Path],
    out: Path,
    slice_ns: int | None,
    lateness_ms: float = 1000.0,
    **engine: object,
) -> ResultsStore:
    core = config(lateness_ms)
    record = {**core.as_record(), "slice_ns": "auto" if slice_ns is None else slice_ns}
    with ResultsStore.create(out, record) as store:
        evaluate_bags(paths, core, store, slice_ns=slice_ns, **engine)  # type: ignore[arg-type]
    return ResultsStore.open(out)


def check_counts(store: ResultsStore, paths: list[Path], none_for: str | None = None) -> None:
    """Every GT frame and every estimate counted once; stored frames named by header stamp.

    Every method scores every frame, but ``none_for``, which scores none.
    """
    for path, sequence in zip(paths, sequence_names(paths), strict=True):
        held = content(path)
        counts = store.match_counts(sequence)
        assert set(counts) == set(METHODS), sequence
        for method, found in counts.items():
            assert found.matched + found.unmatched + found.failed == held.estimates[method], (
                sequence,
                method,
                found,
            )
            assert found.matched + found.dropped + found.failed == len(held.gt_stamps), (
                sequence,
                method,
                found,
            )
            wanted = 0 if method == none_for else len(held.gt_stamps)
            assert (found.matched, found.failed) == (wanted, 0), (sequence, method, found)
        if none_for is None:
            assert store.common_stamps(sequence) == sorted(held.gt_stamps), sequence
        assert store.problems(sequence) == [], sequence


def test_the_copies_are_retimed_as_meant(bags: dict[str, Path]) -> None:
    """The copies hold the same frames, stamps 10 years later, spread over 12 s of log time."""
    for stem in (Path(name).stem for name in BAGS):
        original, spread, late = (
            content(bags[k]) for k in (stem, f"{stem}_spread", f"{stem}_late")
        )
        assert len(original.gt_stamps) in (3, 5)
        assert spread.gt_stamps == [s + YEARS_10 for s in original.gt_stamps]
        assert original.first_gt_offset > 5 * 365 * 86_400 * SECOND  # recorded years later
        assert spread.first_gt_offset < -3 * 365 * 86_400 * SECOND  # now stamped years later
        assert SPREAD_NS <= spread.log_span < SPREAD_NS + SECOND
        assert late.log_span > spread.log_span + SECOND


@pytest.mark.parametrize("slice_s", [1, 2, None, 60], ids=["1", "2", "auto", "60"])
def test_every_frame_whatever_the_slice(
    bags: dict[str, Path], tmp_path: Path, slice_s: int | None
) -> None:
    paths = [
        bags[k] for k in ("sip_kitti", "sip_mb_doffs0", "sip_kitti_spread", "sip_mb_doffs0_spread")
    ]
    store = evaluate(paths, tmp_path, None if slice_s is None else slice_s * SECOND)
    with store:
        check_counts(store, paths)
        for path, sequence in zip(paths, sequence_names(paths), strict=True):
            _, info = store.sequence_info(sequence)
            assert info["stamp_offset_ns"] == content(path).first_gt_offset
            slice_ns = info.get("slice_ns", (slice_s or 0) * SECOND)
            assert ("warning" in info) == (abs(content(path).first_gt_offset) > slice_ns)


@pytest.mark.parametrize("engine", [{"jobs": 2}, {"scheduler": "local:2"}], ids=["jobs2", "dask"])
def test_every_frame_with_other_executors(
    bags: dict[str, Path], tmp_path: Path, engine: dict[str, object]
) -> None:
    paths = [bags[k] for k in ("sip_kitti", "sip_kitti_spread", "sip_mb_doffs0_late")]
    with evaluate(paths, tmp_path, SECOND, 2000.0, **engine) as store:
        check_counts(store, paths)


@pytest.mark.parametrize("slice_s", [1, 2, None, 60], ids=["1", "2", "auto", "60"])
def test_a_late_matcher_within_lateness_is_counted_every_frame(
    bags: dict[str, Path], tmp_path: Path, slice_s: int | None
) -> None:
    paths = [bags["sip_kitti_late"], bags["sip_mb_doffs0_late"]]
    with evaluate(paths, tmp_path, None if slice_s is None else slice_s * SECOND, 2000.0) as store:
        check_counts(store, paths)


def test_a_matcher_later_than_lateness_is_unmatched_and_dropped(
    bags: dict[str, Path], tmp_path: Path
) -> None:
    """1.5 s late with the default 1 s: every SGBM estimate unmatched, every frame dropped by it
    (and nothing lost: BM keeps every frame)."""
    paths = [bags["sip_kitti_late"], bags["sip_mb_doffs0_late"]]
    with evaluate(paths, tmp_path, SECOND) as store:
        check_counts(store, paths, none_for="sgbm")


def test_the_cli_warns_once_per_bag_when_stamps_are_far_from_the_log_time(
    bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["bag", str(bags["sip_kitti"]), str(bags["sip_mb_doffs0_spread"]), "--gt", GT]
    args += [f"--method={name}={topic}" for name, topic in METHODS.items()]
    args += ["--camera-info", *INFOS, "--criteria", "all", "--measures", "density", "bmp"]
    assert (
        main(
            [
                *args,
                "--objective-measures",
                "bmp",
                "--out",
                str(tmp_path),
                "--quiet",
                "--slice",
                "1",
            ]
        )
        == 0
    )
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(warnings) == 2, warnings
    assert (
        "sip_kitti.bag: header stamps are 6.2 years (1.96e+08 s) before the log time" in warnings[0]
    )
    assert "sip_mb_doffs0_spread.bag: header stamps are 3.8 years" in warnings[1]
    assert "after the log time" in warnings[1]


def test_report_thumbnails_find_frames_stamped_years_before_their_log_time(
    bags: dict[str, Path], tmp_path: Path
) -> None:
    """The report reads each chosen frame again around its log time, not its stamp."""
    from dispeval_ros.report.data import error_thumbnails

    path = bags["sip_kitti"]
    with evaluate([path], tmp_path, SECOND) as store:
        thumbnails = error_thumbnails(store, [path], count=2, config=config())
    assert thumbnails is not None
    shown = [int(frame["stamp"]) for frame in thumbnails["frames"]]
    assert len(shown) == 2
    assert set(shown) <= set(content(path).gt_stamps)
    assert all(len(frame["images"]) == len(METHODS) for frame in thumbnails["frames"])


@pytest.fixture(scope="module")
def twice(shared_data: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The KITTI bag recorded twice, 30 s apart in log time, with the same stamps (a looping
    player recorded without re-stamping)."""
    path = tmp_path_factory.mktemp("twice") / "sip_kitti_twice.bag"
    messages = read(shared_data / "stereo-image-proc" / "sip_kitti.bag")
    with Writer(path) as writer:
        connections = {}
        for shift in (0, 30 * SECOND):
            for message in messages:
                if message.topic not in connections:
                    connections[message.topic] = writer.add_connection(
                        message.topic, message.msgtype, typestore=NOETIC
                    )
                data = NOETIC.serialize_ros1(message.msg, message.msgtype)
                writer.write(connections[message.topic], message.log_ns + shift, data)
    return path


@pytest.mark.parametrize("slice_s", [1, 2, 60])
def test_a_frame_logged_again_much_later_is_a_repeat_whatever_the_slice(
    twice: Path, tmp_path: Path, slice_s: int
) -> None:
    """The first copy stands: its frames are scored once, the second copy's estimates find no
    frame (unmatched), each repeated frame is one problem row; never two rows of one stamp."""
    held = content(twice)
    stamps = sorted(set(held.gt_stamps))
    assert len(held.gt_stamps) == 2 * len(stamps) == 10
    with evaluate([twice], tmp_path, slice_s * SECOND) as store:
        for method, found in store.match_counts("sip_kitti_twice").items():
            assert (found.matched, found.unmatched, found.dropped, found.failed) == (5, 5, 0, 0)
            assert held.estimates[method] == 10
        assert store.common_stamps("sip_kitti_twice") == stamps
        problems = store.problems("sip_kitti_twice")
        assert sorted(problem.stamp for problem in problems) == stamps
        assert all("more than once" in problem.message for problem in problems)
