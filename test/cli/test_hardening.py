"""Bad input and hostile conditions: one line, exit 2, nothing lost (issue 12's corpus, growing).

Every case is generated here: damaged or hostile files, databases with parts missing, a full
disk, two runs on one folder, an optional dependency that is not installed.
"""

from __future__ import annotations

import io
import sqlite3
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from sample_feed import sample_bag, sample_config, topic_args

from dispeval_ros.cli.main import main
from dispeval_ros.core import Evaluator
from dispeval_ros.errors import ConfigurationError, InputError
from dispeval_ros.io.files import read_disparity, write_pfm
from dispeval_ros.io.store import RESULTS_FILE, FrameScores, ResultsStore

CONFIG = {"criteria": ["all"], "missing": "interpolate"}


def one_line_error(capsys: pytest.CaptureFixture[str], *needles: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err, err
    return err


def hostile_npy_header(shape: tuple[int, ...]) -> bytes:
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f4", "fortran_order": False, "shape": shape}
    )
    return header.getvalue() + bytes(64)


@pytest.mark.parametrize("shape", [(100_000, 1_800_000), (2**40,), (64, 64)])
def test_npy_headers_are_checked_before_allocating(tmp_path: Path, shape: tuple[int, ...]) -> None:
    npy = tmp_path / "est.npy"
    npy.write_bytes(hostile_npy_header(shape))
    with pytest.raises(InputError, match=r"npy header claims a .* but only 64 bytes follow"):
        read_disparity(npy)
    npz = tmp_path / "est.npz"
    with zipfile.ZipFile(npz, "w") as archive:
        archive.writestr("arr_0.npy", hostile_npy_header(shape))
    with pytest.raises(InputError, match="npy header claims"):
        read_disparity(npz)


def test_object_arrays_are_refused(tmp_path: Path) -> None:
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "|O", "fortran_order": False, "shape": (2,)}
    )
    path = tmp_path / "objects.npy"
    path.write_bytes(header.getvalue() + bytes(16))
    with pytest.raises(InputError, match="Python objects"):
        read_disparity(path)


def test_valid_arrays_still_read(tmp_path: Path) -> None:
    array = np.arange(1, 13, dtype=np.float32).reshape(3, 4)
    np.save(tmp_path / "a.npy", array)
    np.savez(tmp_path / "a.npz", array)
    np.savez_compressed(tmp_path / "b.npz", disparity=array)
    for name in ("a.npy", "a.npz", "b.npz"):
        np.testing.assert_array_equal(read_disparity(tmp_path / name), array)


def test_a_corrupt_png_is_our_one_line_without_opencv_warnings(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    gt = tmp_path / "gt.pfm"
    write_pfm(gt, np.full((40, 60), 10.0, np.float32))
    png = tmp_path / "est.png"
    import cv2

    ok, encoded = cv2.imencode(".png", np.full((40, 60), 2560, np.uint16))
    assert ok
    png.write_bytes(encoded.tobytes()[: len(encoded) // 2])  # truncated mid-stream
    assert main(["eval", "--gt", str(gt), "--est", f"m={png}"]) == 2
    captured = capfd.readouterr()
    assert "WARN" not in captured.err, captured.err  # OpenCV's own log lines
    assert captured.err.count("\n") == 1, captured.err
    assert str(png) in captured.err


# -- results databases ------------------------------------------------------------------------


def some_scores() -> list[FrameScores]:
    evaluator = Evaluator(("all",), ("bmp", "mae", "density"))
    gt = np.full((20, 30), 10.0)
    return [FrameScores("s", k, "m", evaluator.score(gt, gt + 0.5 * k)) for k in range(1, 4)]


def stored_results(folder: Path) -> Path:
    with ResultsStore.create(folder, CONFIG) as store:
        store.add_unit("s", "u0", some_scores())
    return folder


def test_a_second_run_on_the_same_folder_is_refused(tmp_path: Path) -> None:
    first = ResultsStore.create(tmp_path / "out", CONFIG)
    try:
        with pytest.raises(ConfigurationError, match="in use by another dispeval run"):
            ResultsStore.create(tmp_path / "out", CONFIG, resume=True)
    finally:
        first.close()
    ResultsStore.create(tmp_path / "out", CONFIG, resume=True).close()  # free again


def test_a_full_disk_is_one_line_and_keeps_what_was_stored(tmp_path: Path) -> None:
    folder = stored_results(tmp_path / "out")
    store = ResultsStore.create(folder, CONFIG, resume=True)
    try:
        pages = store._db.execute("PRAGMA page_count").fetchone()[0]
        store._db.execute(f"PRAGMA max_page_count = {pages}")  # no room for one more page
        big = [
            FrameScores("s", 100 + k, f"method_{j}", some_scores()[0].scores)
            for k in range(50)
            for j in range(20)
        ]
        with pytest.raises(
            InputError, match=r"cannot write the results \(database or disk is full"
        ):
            store.add_unit("s", "u1", big)
    finally:
        store.close()
    with ResultsStore.open(folder) as reopened:
        assert reopened.stamps("s") == [1, 2, 3]
        assert reopened.done_units("s") == {"u0"}


@pytest.mark.parametrize("table", ["units", "match_counts", "frames", "run"])
def test_a_database_missing_a_table_is_one_line(
    tmp_path: Path, table: str, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = stored_results(tmp_path / "out")
    with sqlite3.connect(folder / RESULTS_FILE) as connection:
        connection.execute(f"DROP TABLE {table}")
    with pytest.raises(InputError, match=f"incomplete \\(no table {table}\\)"):
        ResultsStore.open(folder)
    assert main(["report", str(folder)]) == 2
    one_line_error(capsys, "incomplete", table)


def test_report_png_without_matplotlib_keeps_the_page(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = stored_results(tmp_path / "out")
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # as on a plain `pip install .`
    assert main(["report", str(folder), "--png", str(tmp_path / "png")]) == 2
    captured = capsys.readouterr()
    assert (folder / "report.html").is_file()
    assert "report:" in captured.out
    assert captured.err.count("\n") == 1
    assert 'pip install "dispeval_ros[report]"' in captured.err


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf"])
def test_scales_are_refused_alike_by_eval_and_bag(
    value: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    gt = tmp_path / "gt.pfm"
    write_pfm(gt, np.full((20, 30), 10.0, np.float32))
    assert main(["eval", "--gt", str(gt), "--est", f"m={gt}", "--gt-scale", value]) == 2
    one_line_error(capsys, "--gt-scale must be a finite number > 0")
    assert main(["eval", "--gt", str(gt), "--est", f"m={gt}", "--est-scale", value]) == 2
    one_line_error(capsys, "--est-scale must be a finite number > 0")
    out = tmp_path / "out"
    args = ["bag", str(gt), "--gt", "/gt", "--method", "m=/m", "--out", str(out), "--gt-scale"]
    assert main([*args, value]) == 2
    one_line_error(capsys, "--gt-scale must be a finite number > 0")
    assert not out.exists()  # refused before anything was created


@pytest.mark.parametrize(
    "options",
    [
        ["--width", "100000", "--height", "100000"],
        ["--width", "10"],
        ["--frames", "0"],
        ["--fps", "nan"],
    ],
)
def test_make_bag_refuses_sizes_before_writing(
    options: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "bag"
    assert main(["make-bag", str(out), *options]) == 2
    one_line_error(capsys)
    assert not out.exists()


def test_make_bag_of_a_scene_it_cannot_read_leaves_no_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scene = tmp_path / "scene"
    scene.mkdir()
    (scene / "notes.txt").write_text("not a dataset")
    for out in (tmp_path / "bag", tmp_path / "bag.mcap"):
        storage = "mcap" if out.suffix else "rosbag2-mcap"
        assert main(["make-bag", str(out), "--scene", str(scene), "--storage", storage]) == 2
        one_line_error(capsys, str(scene))
        assert not out.exists()


# -- dispeval bag: every mistake refused before anything is written ---------------------------

BAG_MISTAKES = {
    "typo-topic": ["--method", "typo=/stereo/typo/disparity"],
    "wrong-type": ["--method", "wrong=/stereo/left/camera_info"],
    "jobs-0": ["--jobs", "0"],
    "jobs-and-scheduler": ["--jobs", "2", "--scheduler", "local:2"],
    "negative-tolerance": ["--tolerance", "-1"],
    "nan-lateness": ["--lateness", "nan"],
    "unknown-objective": ["--objective-measures", "a99"],
    "slice-nan": ["--slice", "nan"],
    "slice-inf": ["--slice", "inf"],
    "slice-zero": ["--slice", "0"],
    "gt-scale-zero": ["--gt-scale", "0"],
}


@pytest.mark.parametrize("mistake", sorted(BAG_MISTAKES))
def test_a_refused_bag_run_leaves_nothing_behind(
    mistake: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = sample_bag()
    out = tmp_path / "R"
    args = ["bag", str(bag), *topic_args(sample_config(bag)), "--out", str(out), "--quiet"]
    assert main([*args, *BAG_MISTAKES[mistake]]) == 2
    one_line_error(capsys)
    assert not out.exists()


@pytest.mark.parametrize("which", ["missing", "corrupt", "second-missing"])
def test_a_bad_bag_leaves_nothing_and_the_fixed_command_runs(
    which: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = sample_bag()
    bad = tmp_path / "bad.mcap"
    if which == "corrupt":
        bad.write_bytes(b"\\x89MCAP0\\r\\n" + bytes(100))
    bags = [str(bag), str(bad)] if which == "second-missing" else [str(bad)]
    out = tmp_path / "R"
    topics = topic_args(sample_config(bag))
    assert main(["bag", *bags, *topics, "--out", str(out), "--quiet"]) == 2
    one_line_error(capsys, str(bad))
    assert not out.exists()
    assert main(["bag", str(bag), *topics, "--out", str(out), "--quiet"]) == 0  # no --resume


def test_a_results_folder_that_never_got_a_unit_is_not_results(tmp_path: Path) -> None:
    """A run killed before its first unit: the next run starts afresh, without --resume."""
    ResultsStore.create(tmp_path / "R", {**CONFIG, "delta": 3.0}).close()
    with ResultsStore.create(tmp_path / "R", CONFIG) as store:  # another configuration even
        assert "delta" not in store.config()  # the stale configuration is gone
        store.add_unit("s", "u0", some_scores())
    with pytest.raises(ConfigurationError, match="already holds results"):
        ResultsStore.create(tmp_path / "R", CONFIG)


def test_sizes_read_width_by_height_everywhere(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Headers say W×H (1242×375), so size errors say W×H too."""
    gt = tmp_path / "gt.pfm"
    write_pfm(gt, np.full((40, 60), 10.0, np.float32))
    est = tmp_path / "est.pfm"
    write_pfm(est, np.full((30, 60), 10.0, np.float32))
    assert main(["eval", "--gt", str(gt), "--est", f"m={est}"]) == 2
    one_line_error(capsys, "the estimate is 60×30 but the ground truth is 60×40")


def test_bag_warns_when_camera_info_exists_but_is_not_used(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """DisparityImage f and t carry no doffs: say so, and say which camera was used."""
    bag = sample_bag()
    config = sample_config(bag)
    methods = [a for m, t in config.methods.items() for a in ("--method", f"{m}={t}")]
    out = tmp_path / "R"
    assert main(["bag", str(bag), "--gt", config.gt_topic, *methods, "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "warning:" in captured.err
    assert "/stereo/left/camera_info" in captured.err
    assert "camera: from each DisparityImage's f and t (no doffs)" in captured.out
    args = ["bag", str(bag), *topic_args(config), "--out", str(tmp_path / "S")]
    assert main(args) == 0
    captured = capsys.readouterr()
    assert "warning" not in captured.err
    assert "camera: from CameraInfo /stereo/left/camera_info and" in captured.out
