"""Item 3 of the confidence issue: a matcher with no confidence map, its threshold swept.

``dispeval tune`` with density beside an error measure as the objectives gives the
density–error front (Kostliva & Šára): A* group 1 must be exactly the configurations no other
beats on both (density higher, error lower), checked here from ``tune.csv`` by plain
comparisons, and the front figure is written. Density is higher-is-better: before it was
negated in the summaries' objectives, the sparsest configuration "dominated" all the others.
"""

from __future__ import annotations

import csv
import io
from contextlib import redirect_stdout
from pathlib import Path

import pytest

from dispeval_ros.cli.main import main
from dispeval_ros.report.sweep import DENSITY_FIGURE, SweepPoint, density_front

pytestmark = [pytest.mark.data]

SPACE = """
family: sgbm
parameters:
  uniqueness_ratio: [0, 10, 40]
  correlation_window_size: [5, 15]
  disparity_range: 128
"""
ERROR, DENSITY = "bad_2 (all)", "density (all)"


def test_group_one_is_the_density_error_front(shared_data: Path, tmp_path: Path) -> None:
    space = tmp_path / "space.yaml"
    space.write_text(SPACE)
    out = tmp_path / "out"
    argv = ["tune", "--space", str(space), "--scene", str(shared_data / "kitti-2015" / "000005_10"),
            "--out", str(out), "--missing", "ignore", "--criteria", "all", "--measures", "bad_2",
            "density", "--objective-measures", "bad_2", "density", "--quiet"]  # fmt: skip
    with redirect_stdout(io.StringIO()):
        assert main(argv) == 0
    with (out / "tune.csv").open() as table:
        rows = list(csv.DictReader(table))
    assert len(rows) == 6
    values = {r["method"]: (float(r[DENSITY]), float(r[ERROR])) for r in rows}
    beaten = {
        name
        for name, (density, error) in values.items()
        for other, (d, e) in values.items()
        if other != name and d >= density and e <= error and (d, e) != (density, error)
    }
    front = set(values) - beaten
    assert {r["method"] for r in rows if r["group"] == "1"} == front
    assert 1 < len(front) < len(values)  # a trade-off, and something off the front
    points = [SweepPoint(n, {}, {DENSITY: d, ERROR: e}, 1) for n, (d, e) in values.items()]
    assert {p.name for p in density_front(points, ERROR, DENSITY)} == front
    assert (out / "figures" / DENSITY_FIGURE).stat().st_size > 1000


def test_the_front_of_hand_worked_points() -> None:
    def point(name: str, density: float, error: float) -> SweepPoint:
        return SweepPoint(name, {}, {DENSITY: density, ERROR: error}, 1)

    points = [point("a", 0.9, 20.0), point("b", 0.8, 10.0), point("c", 0.7, 12.0),
              point("d", 0.5, 4.0), point("e", 0.5, 5.0), point("f", 0.4, float("nan"))]  # fmt: skip
    assert [p.name for p in density_front(points, ERROR, DENSITY)] == ["a", "b", "d"]
