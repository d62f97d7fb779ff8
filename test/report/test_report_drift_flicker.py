"""The report's temporal section shows the LiDAR drift between scans and the flicker of a static
camera where a bag run recorded them: every cell equals summary.json's number, each table headed
as noise, not accuracy (the bags of test_bag_lidar_drift.py and test_bag_flicker.py)."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "offline"))  # their bag fixtures
from test_bag_flicker import root, static_run  # noqa: F401  (fixtures)
from test_bag_lidar_drift import command, drive  # noqa: F401  (fixtures)
from test_report import browser, open_report  # noqa: F401  (browser fixture)

from dispeval_ros.cli.main import main


def report_of(out: Path) -> dict[str, Any]:
    assert main(["report", str(out), "--quiet"]) == 0
    return json.loads((out / "summary.json").read_text())


def expected_rows(entry: dict[str, Any], runs: str, count: str, columns: list[str]) -> list:
    return [
        [m, c, e[runs], v[count], *(v[q] for q in columns)]
        for m, e in entry["methods"].items()
        if e["criteria"]
        for c, v in e["criteria"].items()
    ]


def check_table(page: Any, table: str, expected: list) -> None:
    cells = page.eval_on_selector_all(
        f"#{table} tbody tr", "rows => rows.map(r => Array.from(r.cells).map(c => c.textContent))"
    )
    assert len(cells) == len(expected)
    for row, values in zip(cells, expected, strict=True):
        assert row[:2] == values[:2]
        for text, value in zip(row[2:], values[2:], strict=True):  # fmt: 4 or 5 digits
            assert float(text) == pytest.approx(value, rel=5e-4, abs=1e-12), (row, values)
    assert "noise, not accuracy" in page.text_content(f"#{table} thead")


def test_the_drift_table_shows_summary_jsons_numbers(
    browser: Any,  # noqa: F811
    drive: Path,  # noqa: F811
    tmp_path: Path,
) -> None:
    out = tmp_path / "res"
    assert main(command(drive, out)) == 0
    (sequence,) = report_of(out)["sequences"]
    page, errors = open_report(browser, out / "report.html")
    state = page.evaluate("window.dispevalTemporal()")
    (name,) = state["sequences"]
    columns = ["counted", "mean", "rms", "bad_0.5", "bad_1", "bad_2", "bad_4", "bias_drift"]
    expected = expected_rows(sequence["lidar_drift"], "pairs", "n", columns)
    assert state["sequences"][name]["drift"] == expected
    check_table(page, f"temporal-drift-{name}", expected)
    assert not errors


def test_the_flicker_table_shows_summary_jsons_numbers(
    browser: Any,  # noqa: F811
    static_run: Path,  # noqa: F811
) -> None:
    (sequence,) = report_of(static_run)["sequences"]
    page, errors = open_report(browser, static_run / "report.html")
    state = page.evaluate("window.dispevalTemporal()")
    (name,) = state["sequences"]
    entry = sequence["flicker"]
    first = next(iter(next(iter(entry["methods"].values()))["criteria"].values()))
    columns = ["mean_abs", "rms", *(k for k in first if k.startswith("bad_"))]
    expected = expected_rows(entry, "windows", "n_residual", columns)
    assert state["sequences"][name]["flicker"] == expected
    check_table(page, f"temporal-flicker-{name}", expected)
    assert not errors
