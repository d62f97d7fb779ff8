"""The report's parameter-sweep section: a ``dispeval tune`` database shows its configurations
with their values (``tune.csv``'s rows, bit for bit) and the sweep's figures; any other database
shows nothing of it."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import pytest
from test_report import browser, make_small_store, open_report  # noqa: F401  (browser fixture)

from dispeval_ros.cli.main import main
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.report.sweep import PARALLEL_FIGURE, SENSITIVITY_PREFIX, sweep_data

SPACE = """family: sgbm
parameters:
  correlation_window_size: [5, 7]
  uniqueness_ratio: [5, 15]
  disparity_range: 64
"""


def page_data(html: Path) -> dict[str, Any]:
    payload = html.read_text("utf-8").split('id="dispeval-data">')[1].split("</script>")[0]
    return json.loads(payload)


@pytest.fixture(scope="module")
def swept(shared_data: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    root = tmp_path_factory.mktemp("report_sweep")
    (root / "space.yaml").write_text(SPACE)
    out = root / "tune"
    scene = shared_data / "middeval3-training-Q" / "ArtL"
    argv = ["tune", "--space", str(root / "space.yaml"), "--scene", str(scene), "--out", str(out)]
    assert main([*argv, "--quiet"]) == 0
    assert main(["report", str(out), "--quiet"]) == 0
    with (out / "tune.csv").open(newline="") as handle:
        table = list(csv.reader(handle))
    return {"out": out, "data": page_data(out / "report.html")["sweep"], "table": table}


def test_the_rows_are_tune_csvs(swept: dict[str, Any]) -> None:
    data, (header, *rows) = swept["data"], swept["table"]
    assert data["recorded"]
    assert data["configurations"] == len(rows) == 4
    assert data["parameters"] == ["correlation_window_size", "uniqueness_ratio"]
    for shown, row in zip(data["rows"], rows, strict=True):
        by = dict(zip(header, row, strict=True))
        assert shown[:3] == [by["method"], int(by["group"]), by["reduced"] == "1"]
        assert shown[3:5] == [int(by[p]) for p in data["parameters"]]
        assert shown[5:] == [float(by[m]) for m in data["measures"]]  # repr round trip: exact
    assert set(data["figures"]) == {
        PARALLEL_FIGURE,
        *(f"{SENSITIVITY_PREFIX}{p}.png" for p in data["parameters"]),
    }
    assert all(uri.startswith("data:image/png;base64,") for uri in data["figures"].values())


def test_another_database_shows_nothing_of_it(tmp_path: Path) -> None:
    with ResultsStore.open(make_small_store(tmp_path)) as store:
        assert sweep_data(store) == {"recorded": False}


def test_the_page_shows_the_table_and_figures(browser: Any, swept: dict[str, Any]) -> None:  # noqa: F811
    page, errors = open_report(browser, swept["out"] / "report.html")
    cells = page.eval_on_selector_all(
        "#sweep-table tbody tr", "rows => rows.map(r => [...r.cells].map(c => c.textContent))"
    )
    data = swept["data"]
    assert [row[0] for row in cells] == [row[0] for row in data["rows"]]
    assert [row[3:5] for row in cells] == [[str(v) for v in row[3:5]] for row in data["rows"]]
    images = page.eval_on_selector_all("#sweep-view img", "imgs => imgs.map(i => i.naturalWidth)")
    assert len(images) == len(data["figures"])
    assert all(width > 100 for width in images)
    assert not errors
