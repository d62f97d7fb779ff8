"""What the command line prints: widths, number formats, objectives, plurals (issue 23).

Each rule is checked on what the commands print for real inputs: the demo (robot mode),
``make-bag`` + ``bag`` (dense GT and LiDAR), ``models`` of stored results, ``eval`` of a KITTI
frame whose official GT has no disparity jump (so ``boundary`` is empty).
"""

from __future__ import annotations

import contextlib
import csv
import io
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dispeval_ros.cli.main import main
from dispeval_ros.cli.output import WIDTH, column_format, plural, table
from dispeval_ros.cli.progress import Progress
from dispeval_ros.cli.summary import models_text
from dispeval_ros.core import evaluate_models
from dispeval_ros.core.criteria import DEPTH, LEGACY, TEXTURE, VISIBILITY
from dispeval_ros.core.criteria.empty import EMPTY_REASONS, empty_reason
from dispeval_ros.core.objectives import objective_matrix
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import CLOUD_TOPIC, GT_TOPIC, LEFT_INFO, RIGHT_INFO
from dispeval_ros.report.data import default_selection, evaluate_selection
from dispeval_ros.summary import summarize

STAMP = re.compile(r"\d{15,}")
"""A nanosecond stamp as printed (the synthetic drive's start: 1.7·10¹⁸ ns)."""
METHODS = ["--method", "sgbm=/stereo/sgbm/disparity", "--method", "bm=/stereo/bm_fast/disparity"]
CAMERA = ["--camera-info", LEFT_INFO, RIGHT_INFO]


def _too_wide(text: str) -> list[str]:
    return [line for line in text.splitlines() if len(line) > WIDTH]


def _run(capsys: Any, *args: str) -> str:
    capsys.readouterr()
    assert main(list(args)) == 0
    return str(capsys.readouterr().out)


@pytest.fixture(autouse=True)
def _wide_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    """A terminal wider than 100 columns: the tables must still fit 100."""
    monkeypatch.setenv("COLUMNS", "240")


# -- number formats -------------------------------------------------------------------------


def test_a_column_has_one_number_format_chosen_from_its_values() -> None:
    mixed = column_format([8.999e5, 47058.0248, float("nan")])
    assert [mixed(v) for v in (8.999e5, 47058.0248, float("nan"))] == [
        "8.999e+05",
        "4.706e+04",
        "-",
    ]
    fixed = column_format([0.65, 1654.631, 0.0])
    assert [fixed(v) for v in (0.65, 1654.631, 0.0)] == ["0.6500", "1654.6310", "0.0000"]
    assert column_format([3.0, 25])(3.0) == "3"
    text = table(["method", "bmpre"], [["a", 1.107e5], ["b", 45115.714]])
    written = [line.split()[-1] for line in text.splitlines()[2:]]
    assert written == ["1.107e+05", "4.512e+04"]


def test_counts_read_as_english() -> None:
    assert plural(1, "objective") == "1 objective"
    assert plural(14, "objective") == "14 objectives"
    assert plural(0, "frame") == "0 frames"
    result = evaluate_models(["a", "b"], np.array([[1.0], [2.0]]))
    assert models_text(result, ["all/sze"]).startswith("A* Groups over 1 objective (all/sze)")


def test_make_bag_progress_counts_frames_not_slices() -> None:
    stream = io.StringIO()
    progress = Progress("dispeval make-bag: writing", stream=stream, unit="frames")
    progress.update(1, 20, 1)
    assert re.fullmatch(
        r"dispeval make-bag: writing \[#? *\] 1/20 frames  \d+\.\d frames/s\n", stream.getvalue()
    )


# -- empty criteria --------------------------------------------------------------------------


def test_every_criterion_class_says_why_it_can_be_empty() -> None:
    classes = {"all", *VISIBILITY, *DEPTH, *LEGACY, *TEXTURE, "roi", "elsewhere", "unlabelled"}
    assert classes <= set(EMPTY_REASONS)
    assert "4-neighbours" in empty_reason("boundary")
    assert empty_reason("gtfree:textured") == EMPTY_REASONS["textured"]
    assert "depth range" in empty_reason("30+m")


def test_a_criterion_without_points_is_no_objective() -> None:
    def row(n: float, sze: float) -> dict[str, float]:
        return {"n": n, "sze": sze, "bmpre": sze / 10}

    scores = {
        "a": {"all": row(10, 4.0), "boundary": row(0, 0.0)},
        "b": {"all": row(10, 5.0), "boundary": row(0, 0.0)},
    }
    _methods, names, matrix = objective_matrix(scores, ["sze", "bmpre"])
    assert names == ["all/sze", "all/bmpre"]
    assert matrix.shape == (2, 2)


def test_kitti_boundary_is_empty_said_and_no_objective(shared_data: Path, capsys: Any) -> None:
    import json

    scene = shared_data / "kitti-lidar" / "kitti2015-with-velodyne"
    est = ["--est", f"psmnet={scene / 'prediction' / '000010.png'}"]
    shifted = ["--est", f"also={scene / 'prediction' / '000010.png'}", "--frame", "000010"]
    text = _run(capsys, "eval", "--scene", str(scene), *est, *shifted)
    assert "boundary: no point — the GT has no disparity jump > 2 px" in text
    assert "A* Groups over 12 objectives" in text
    document = json.loads(_run(capsys, "eval", "--scene", str(scene), *est, *shifted, "--json"))
    assert document["partition"]["boundary"] == 0
    assert document["objectives"]
    assert not any(o.startswith("boundary/") for o in document["objectives"])
    assert not _too_wide(text.split("\n", 1)[1])  # the 'ground truth:' path line aside


def test_protocol_reports_fit_100_columns(shared_data: Path, capsys: Any) -> None:
    """The benchmark tables (MiddEval3 has 12 columns) are split, the header lines wrapped."""
    scene = shared_data / "middeval3-training-Q" / "Teddy"
    text = _run(capsys, "eval", "--protocol", "middeval3", "--scene", str(scene), "--est",
                f"gt={scene / 'disp0GT.pfm'}")  # fmt: skip
    assert "summary, region" in text
    assert not _too_wide(text)


def test_stored_results_leave_the_empty_criterion_out(
    shared_data: Path, tmp_path: Path, capsys: Any
) -> None:
    bag, out = tmp_path / "k5", tmp_path / "results"
    _run(capsys, "make-bag", str(bag), "--scene", str(shared_data / "kitti-2015" / "000005_10"))
    text = _run(capsys, "bag", str(bag), "--gt", GT_TOPIC, *CAMERA, *METHODS, "--out", str(out))
    assert "boundary: no point" in text
    for granularity in ("sequence", "frame"):
        exported = tmp_path / f"{granularity}.csv"
        args = ["--objectives", granularity, "--export", str(exported)]
        printed = _run(capsys, "models", str(out), *args)
        assert "A* Groups over 12 objectives" in printed
        with exported.open() as handle:
            header = next(csv.reader(handle))
        assert len(header) == 13
        assert not any(h.startswith("boundary/") for h in header)
    with ResultsStore.open(out) as store:  # the report compares what the summary compares
        _, names, _, _ = evaluate_selection(store, default_selection(store))
        assert names == summarize(store).overall_objectives
        assert len(names) == 12


# -- the first hour: demo, make-bag, bag (dense and LiDAR), models ----------------------------


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str, str]:
    """A 3-frame synthetic drive, what make-bag printed and its progress lines."""
    folder = tmp_path_factory.mktemp("tables")
    bag = folder / "drive.mcap"
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        assert main(["make-bag", str(bag), "--storage", "mcap", "--frames", "3"]) == 0
    return bag, out.getvalue(), err.getvalue()


def test_make_bag_prints_fit_and_read_right(drive: tuple[Path, str, str]) -> None:
    _bag, printed, progress = drive
    assert printed.startswith("wrote 3 frames to ")
    assert not _too_wide(printed)
    assert progress.splitlines()[-1].startswith("dispeval make-bag: writing [")
    assert re.search(r"\] 3/3 frames  \d+\.\d frames/s$", progress.splitlines()[-1])


def test_one_frame_reads_as_one_frame(tmp_path: Path, capsys: Any) -> None:
    args = ["--frames", "1", "--width", "64", "--height", "32", "--no-lidar"]
    printed = _run(capsys, "make-bag", str(tmp_path / "one"), *args)
    assert printed.startswith("wrote 1 frame to ")


def test_lidar_run_prints_its_depth_measures(
    drive: tuple[Path, str, str], tmp_path: Path, capsys: Any
) -> None:
    bag = drive[0]
    args = ["bag", str(bag), "--gt-cloud", CLOUD_TOPIC, *CAMERA, *METHODS, "--quiet"]
    text = _run(capsys, *args, "--out", str(tmp_path / "lidar"))
    block = text.split("criterion: all (summed over the common frames)")[1].split("criterion:")[0]
    for header in ("mae_z [m]", "rmse_z [m]", "absrel_z [ratio]", "irmse [1/km]"):
        assert header in block
    dense = ["bag", str(bag), "--gt", GT_TOPIC, *CAMERA, *METHODS, "--quiet"]
    assert "mae_z" not in _run(capsys, *dense, "--out", str(tmp_path / "dense"))
    assert not _too_wide(text)


def test_frame_objectives_print_frame_numbers_and_export_stamps(
    drive: tuple[Path, str, str], tmp_path: Path, capsys: Any
) -> None:
    bag = drive[0]
    out = tmp_path / "results"
    _run(capsys, "bag", str(bag), "--gt", GT_TOPIC, *CAMERA, *METHODS, "--quiet", "--out", str(out))
    exported = tmp_path / "objectives.csv"
    args = ["models", str(out), "--objectives", "frame", "--export", str(exported)]
    printed = _run(capsys, *args)
    assert "all/sze @drive:f00" in printed
    assert not STAMP.search(printed)
    assert not _too_wide(printed)
    with exported.open() as handle:
        header = next(csv.reader(handle))
    assert all(STAMP.search(name) for name in header[1:])  # scripts join on the stamp


def test_demo_fits_100_columns_and_labels_its_progress(tmp_path: Path, capsys: Any) -> None:
    assert main(["demo", "--out", str(tmp_path / "demo")]) == 0
    captured = capsys.readouterr()
    text = captured.out.split("\n", 1)[1]  # 'sample bag: PATH' aside
    assert not _too_wide(text.rsplit("\nresults: ", 1)[0])
    assert "robot mode" in text
    assert "mae_z [m] LiDAR" in text
    labels = {line.split(" [")[0] for line in captured.err.splitlines() if " [" in line}
    assert labels == {"dispeval demo: dense GT", "dispeval demo: robot mode (LiDAR GT)"}
