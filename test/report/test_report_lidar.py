"""The report of LiDAR and ground-truth-free runs, and what its figures label.

A LiDAR run's error maps are scattered points: drawn enlarged over the dimmed left image on a
scale from the points' own errors (not the dense maps' 0–4 px), and the header says the ground
truth is a projected scan. Figures label their axes with units read from the measure registry,
number frames with whole numbers, and the HTML bar charts are wide enough for their titles.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from test_report import browser, open_report  # noqa: F401  (the browser fixture)

from dispeval_ros.cli.main import main
from dispeval_ros.core import registry
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import (
    CLOUD_TOPIC,
    LEFT_IMAGE,
    LEFT_INFO,
    RIGHT_IMAGE,
    RIGHT_INFO,
    disparity_topic,
    synthetic_frames,
    write_bag,
)
from dispeval_ros.report import figures
from dispeval_ros.report.data import Selection, build_report_data, default_selection
from dispeval_ros.report.html import write_report
from dispeval_ros.report.maps import (
    BACKGROUND_LEVEL,
    ERROR_RANGE_PX,
    POINT_RADIUS,
    SPARSE_QUANTILE,
    SparseMap,
    colour_points,
    error_thumbnails,
    nice_ceiling,
    sparse_scale,
)
from dispeval_ros.report.reference import reference_text
from dispeval_ros.testbed import default_methods
from dispeval_ros.testbed.lidar import LidarModel

WIDTH, HEIGHT, FRAMES, FPS = 248, 76, 3, 10.0
METHODS = ("bm_fast", "sgbm")


@pytest.fixture(scope="module")
def lidar_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A LiDAR drive and its ``dispeval bag --gt-cloud`` results folder."""
    root = tmp_path_factory.mktemp("lidar_report")
    bag = root / "drive"
    methods = [m for m in default_methods(WIDTH) if m.name in METHODS]
    frames = synthetic_frames(FRAMES, WIDTH, HEIGHT, FPS, seed=5, lidar=LidarModel())
    write_bag(bag, frames, methods=methods, fps=FPS)
    args = ["bag", str(bag), "--gt-cloud", CLOUD_TOPIC, "--camera-info", LEFT_INFO, RIGHT_INFO]
    for name in METHODS:
        args += ["--method", f"{name}={disparity_topic(name)}"]
    assert main([*args, "--out", str(root / "results"), "--quiet"]) == 0
    return bag, root / "results"


# -- what the scores are measured against ----------------------------------------------------


def test_header_of_a_lidar_run_says_the_gt_is_a_projected_scan(
    lidar_run: tuple[Path, Path],
) -> None:
    _, results = lidar_run
    with ResultsStore.open(results) as store:
        data = build_report_data(store)
    reference = data["reference"]
    assert reference.startswith(f"ground truth: projected LiDAR scan {CLOUD_TOPIC}")
    assert "sparse points" in reference
    assert "/tf_static" in reference  # no --extrinsic: the chain was read from /tf_static


def test_reference_of_gt_free_and_dense_runs() -> None:
    images = {"images": [LEFT_IMAGE, RIGHT_IMAGE]}
    free = reference_text({"gt_kind": "none", "gt_topic": LEFT_IMAGE, **images})
    assert free is not None
    assert free.startswith("no ground truth: ")
    assert f"images {LEFT_IMAGE} and {RIGHT_IMAGE}" in free
    assert "vpe, lrc" in free
    dense = reference_text({"gt_kind": "disparity", "gt_topic": "/gt"})
    assert dense == "ground truth: disparity images /gt"
    both = reference_text({"gt_kind": "disparity", "gt_topic": "/gt", **images})
    assert both is not None
    assert both.startswith("ground truth: disparity images /gt; and ")
    cloud = reference_text({"gt_kind": "pointcloud", "gt_topic": "/c", "extrinsic": [1.0] * 16})
    assert cloud is not None
    assert "extrinsic given with the run" in cloud
    assert reference_text({}) is None  # results that record no configuration say nothing


# -- sparse error maps -----------------------------------------------------------------------


def test_sparse_scale_is_a_round_number_above_the_points_percentile() -> None:
    error = np.full((10, 40), np.nan, np.float32)
    error[2, :] = np.linspace(0.0, 1.9, 40)  # 40 valid points, 95th percentile ≈ 1.8
    error[7, 0] = 300.0  # one wild point does not set the scale (a maximum would)
    points = SparseMap.of(error)
    assert points.errors.size == 41  # NaN (not evaluated) left out
    top, count = sparse_scale([points])
    assert count == 41
    assert top == nice_ceiling(float(np.percentile(points.errors, SPARSE_QUANTILE))) == 2.0
    assert [nice_ceiling(v) for v in (0.3, 1.0, 1.2, 2.1, 3.0, 7.0, 12.0)] == [
        0.5, 1.0, 2.0, 2.5, 5.0, 10.0, 20.0,
    ]  # fmt: skip
    assert sparse_scale([]) == (ERROR_RANGE_PX, 0)


def test_sparse_points_are_drawn_enlarged_over_the_dimmed_left_image() -> None:
    error = np.full((20, 30), np.nan, np.float32)
    error[10, 15] = 8.0  # at the top of the scale: turbo's last colour
    background = np.full((20, 30), 200, np.uint8)
    rgb = colour_points(SparseMap.of(error), 8.0, background, max_width=30)
    side = 2 * POINT_RADIUS + 1
    lit = np.any(rgb != int(200 * BACKGROUND_LEVEL), axis=2)
    assert lit.sum() == side * side >= 9  # one point: a square, not one pixel
    rows, cols = np.nonzero(lit)
    assert (rows.min(), cols.min()) == (10 - POINT_RADIUS, 15 - POINT_RADIUS)
    assert tuple(rgb[10, 15]) != (255, 255, 255)
    assert rgb[0, 0].tolist() == [int(200 * BACKGROUND_LEVEL)] * 3  # the dimmed left image
    assert 0 < rgb[0, 0, 0] < 200  # shown (not black), and dimmed under the points


def test_lidar_thumbnails_are_coloured_points_on_a_scale_from_their_errors(
    lidar_run: tuple[Path, Path],
) -> None:
    import base64

    import cv2

    bag, results = lidar_run
    with ResultsStore.open(results) as store:
        thumbnails = error_thumbnails(store, [bag], count=2)
    assert thumbnails is not None
    assert thumbnails["sparse"] is True
    top = thumbnails["max_error"]
    assert top == nice_ceiling(top)
    assert top != ERROR_RANGE_PX
    assert (
        "each scored LiDAR point drawn enlarged over the dimmed left image" in (thumbnails["note"])
    )
    assert LEFT_IMAGE in thumbnails["note"]
    for frame in thumbnails["frames"]:
        for _, uri in frame["images"]:
            raw = np.frombuffer(base64.b64decode(uri.split(",", 1)[1]), np.uint8)
            hsv = cv2.cvtColor(cv2.imdecode(raw, cv2.IMREAD_COLOR), cv2.COLOR_BGR2HSV)
            # coloured (turbo) where points are: the old rendering was grey specks on black
            assert np.mean(hsv[..., 1] > 80) > 0.2
            assert np.mean(hsv[..., 2] < 10) < 0.5  # not almost black


# -- figures: units from the registry, whole frame numbers -----------------------------------


def _captured(monkeypatch: pytest.MonkeyPatch) -> dict[str, Any]:
    drawn: dict[str, Any] = {}
    for name in ("curves_figure", "criteria_bars_figure", "group_table_figure"):
        original = getattr(figures, name)

        def capture(*args: Any, _original: Any = original, _name: str = name, **kw: Any) -> Any:
            drawn[_name] = _original(*args, **kw)
            return drawn[_name]

        monkeypatch.setattr(figures, name, capture)
    return drawn


def test_figure_axes_carry_the_registry_unit_and_whole_frame_numbers(
    lidar_run: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, results = lidar_run
    mae = registry.BY_NAME["mae"]
    monkeypatch.setitem(registry.BY_NAME, "mae", dataclasses.replace(mae, unit="furlong"))
    drawn = _captured(monkeypatch)
    with ResultsStore.open(results) as store:
        default = default_selection(store)
        selection = Selection(default.sequences, default.criteria, ("mae",), default.methods)
        figures.write_figures(store, tmp_path / "png", selection)
    curves, bars = drawn["curves_figure"], drawn["criteria_bars_figure"]
    assert curves.get_supylabel() == "mae [furlong]"
    assert curves.axes[0].get_title(loc="left").startswith("mae [furlong] of criterion")
    for axes in bars.axes:
        if axes.get_visible() and axes.axison:
            assert axes.get_ylabel() == "mae [furlong]"
    assert bars.get_suptitle().startswith("mae [furlong] per criterion")
    header = drawn["group_table_figure"].axes[0].get_title(loc="left")
    assert "projected LiDAR scan" in header


def test_frame_ticks_are_whole_numbers(tmp_path: Path) -> None:
    frames = 20  # matplotlib's own choice here is 2.5, 5, 7.5, …
    values = np.linspace(1.0, 3.0, frames * 2).reshape(frames, 2)
    figure = figures.curves_figure(
        values, np.zeros((frames, 2), bool), ["a", "b"], "bmp", "all", False,
        tmp_path / "c.png", unit="%",
    )  # fmt: skip
    ticks = [t for t in figure.axes[-1].get_xticks() if 1 <= t <= frames]
    assert len(ticks) >= 3
    assert all(float(t).is_integer() for t in ticks), ticks


# -- the page: header and bar titles ---------------------------------------------------------


def test_page_shows_the_reference_and_whole_bar_titles(
    browser: Any,  # noqa: F811
    lidar_run: tuple[Path, Path],
    tmp_path: Path,
) -> None:
    _, results = lidar_run
    with ResultsStore.open(results) as store:
        data = build_report_data(store)
    path = tmp_path / "lidar.html"
    write_report(data, path)
    page, errors = open_report(browser, path)
    assert (page.text_content("#reference") or "") == data["reference"]
    # the narrowest charts (one method) with the longest measure label: "bmp_count [points]"
    page.locator('input[data-kind="method"][data-index="1"]').click()
    longest = max(data["measures"], key=lambda q: len(q["name"] + q["unit"]))
    page.select_option("#plot-measure", str(data["measures"].index(longest)))
    titles = page.evaluate(
        """Array.from(document.querySelectorAll('svg.bar-chart')).map(function (svg) {
             return Array.from(svg.querySelectorAll('text.chart-title, text.chart-subtitle'))
               .map(function (t) { const b = t.getBBox(); return [t.textContent, b.x + b.width,
                 Number(svg.getAttribute('width'))]; }); })"""
    )
    assert titles
    assert all(len(chart) == 2 for chart in titles)
    for chart in titles:
        for text, right, width in chart:
            assert right <= width, (text, right, width)  # never cut ("occluded · sz")
    assert titles[0][1][0] == f"{longest['name']} [{longest['unit']}]"  # unit: the registry's
    assert not errors, errors
    page.close()


def _report_on_a_terminal(*args: str) -> tuple[int, str, str]:
    """``dispeval report ARGS`` with stderr on a pseudo-terminal: code, stdout, stderr."""
    import os
    import pty

    parent, child = pty.openpty()
    try:
        done = subprocess.run(
            [sys.executable, "-m", "dispeval_ros", "report", *args],
            stdout=subprocess.PIPE, stderr=child, text=True, timeout=300, check=False,
        )  # fmt: skip
        os.close(child)
        chunks = []
        while True:
            try:
                chunk = os.read(parent, 65536)
            except OSError:  # the terminal is closed once read empty (Linux: EIO)
                break
            if not chunk:
                break
            chunks.append(chunk)
    finally:
        os.close(parent)
    return done.returncode, done.stdout, b"".join(chunks).decode().replace("\r\n", "\n")


def test_report_says_what_it_is_doing_on_a_terminal(
    lidar_run: tuple[Path, Path], tmp_path: Path
) -> None:
    bag, results = lidar_run
    code, _, err = _report_on_a_terminal(
        str(results), "--bag", str(bag), "--thumbnails", "2", "-o", str(tmp_path / "r.html"),
        "--png", str(tmp_path / "png"),
    )  # fmt: skip
    assert code == 0, err
    lines = err.splitlines()
    assert any("error maps: scoring 2 frames again" in line for line in lines), lines
    assert any("error maps: frame 2/2 done" in line for line in lines), lines
    assert any("figures: importing matplotlib" in line for line in lines), lines
    assert all(line.startswith("report: [") for line in lines), lines
    code, _, err = _report_on_a_terminal(str(results), "--quiet", "-o", str(tmp_path / "q.html"))
    assert code == 0, err
    assert err == ""
    # not on a terminal (a log, a pipe): nothing, so that a refusal stays one line
    piped = subprocess.run(
        [sys.executable, "-m", "dispeval_ros", "report", str(results), "--bag", str(bag),
         "--thumbnails", "1", "-o", str(tmp_path / "p.html")],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert piped.returncode == 0, piped.stderr
    assert piped.stderr == ""
