"""The report's temporal-consistency section: pooled TEPE, the ego-motion residual, per pair.

On a drive bag run with ``--temporal --egomotion`` (:func:`bag_support.noisy_biased_drive`:
``noisy`` has 0.5 px of noise per frame, ``biased`` a constant 1.5 px): the page's numbers are
summary.json's ``temporal`` and ``egomotion`` entries, the per-pair TEPE equals plain numpy from
the definition on the maps the bag was made of, the residual is labelled as noise, and a
database written before the pairs tables were shows nothing of it (page and PNGs).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bag_support import NOISY_BIASED, as_written_before, noisy_biased_drive, numpy_pair_errors
from test_report import browser, open_report  # noqa: F401  (browser fixture)

from dispeval_ros.cli.main import main
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.report.figures import FIGURES
from dispeval_ros.report.temporal import (
    NOISE_NOTE,
    TEMPORAL_FIGURE,
    temporal_data,
    temporal_figure,
)

FRAMES, WIDTH, HEIGHT = 6, 320, 96


def page_data(html: Path) -> dict[str, Any]:
    payload = html.read_text("utf-8").split('id="dispeval-data">')[1].split("</script>")[0]
    return json.loads(payload)


@pytest.fixture(scope="module")
def paired(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    root = tmp_path_factory.mktemp("report_temporal")
    args = noisy_biased_drive(root, FRAMES, WIDTH, HEIGHT)
    out = root / "res"
    assert main([*args, "--temporal"]) == 0
    assert main(["report", str(out), "--png", str(root / "png"), "--quiet"]) == 0
    old = root / "old"
    as_written_before(out, old, "pairs", "motion_pairs")
    assert main(["report", str(old), "--png", str(root / "old_png"), "--quiet"]) == 0
    return {
        "root": root,
        "out": out,
        "old": old,
        "summary": json.loads((out / "summary.json").read_text()),
        "data": page_data(out / "report.html"),
        "old_data": page_data(old / "report.html"),
    }


def numpy_tepe(root: Path, method: str) -> list[float]:
    """Per pair of consecutive frames, TEPE from its definition (pixels with GT in both)."""
    return [float(e.mean()) for e in numpy_pair_errors(root, method, FRAMES, WIDTH, HEIGHT)]


def test_the_pooled_numbers_are_summary_jsons(paired: dict[str, Any]) -> None:
    (sequence,) = paired["summary"]["sequences"]
    temporal = paired["data"]["temporal"]
    assert temporal["recorded"]
    block = temporal["sequences"]["drive"]
    assert block["temporal"] == sequence["temporal"]
    assert block["egomotion"] == sequence["egomotion"]
    assert set(block["temporal"]) == set(NOISY_BIASED) == set(block["egomotion"])
    assert block["tepe_measures"][0] == "tepe"
    assert block["tepe_headers"][0] == "tepe [px]"
    assert block["residual_columns"] == ["mean_abs", "rms", "bad_0.5", "bad_2", "bad_4"]
    assert all(c.startswith("gtfree:") for c in block["egomotion"]["noisy"]["criteria"])
    assert "not accuracy" in temporal["noise_note"]


def test_the_per_pair_tepe_is_numpys_and_the_residual_tells_noise_from_bias(
    paired: dict[str, Any],
) -> None:
    block = paired["data"]["temporal"]["sequences"]["drive"]
    for method in NOISY_BIASED:
        series = block["tepe_series"][method]
        assert series["criterion"] == "all"
        assert [frame for frame, _ in series["values"]] == list(range(1, FRAMES))
        values = [v for _, v in series["values"]]
        np.testing.assert_allclose(values, numpy_tepe(paired["root"], method), rtol=1e-6)
        assert block["residual_series"][method]["criterion"] == "gtfree:all"
    assert max(v for _, v in block["tepe_series"]["biased"]["values"]) < 1e-4  # a constant bias
    noisy = [v for _, v in block["residual_series"]["noisy"]["values"]]
    biased = [v for _, v in block["residual_series"]["biased"]["values"]]
    assert len(noisy) == len(biased) == FRAMES - 1
    assert all(b < n for b, n in zip(biased, noisy, strict=True))


def test_an_older_database_shows_nothing_new(paired: dict[str, Any]) -> None:
    assert paired["old_data"]["temporal"] == {"recorded": False}
    written = {p.name for p in (paired["root"] / "old_png").iterdir()}
    assert TEMPORAL_FIGURE not in written
    assert set(FIGURES) <= written
    with ResultsStore.open(paired["old"]) as store:
        assert temporal_data(store) == {"recorded": False}


def test_a_run_without_pairs_shows_nothing_new(paired: dict[str, Any], tmp_path: Path) -> None:
    root = paired["root"]
    args = noisy_biased_drive(tmp_path, 3, 192, 64)
    args.remove("--egomotion")
    assert main(args) == 0
    with ResultsStore.open(tmp_path / "res") as store:
        assert store.records_pairs()
        assert temporal_data(store) == {"recorded": False}
    del root


def test_the_png_plots_each_methods_pairs_and_labels_the_residual_noise(
    paired: dict[str, Any],
) -> None:
    assert (paired["root"] / "png" / TEMPORAL_FIGURE).stat().st_size > 0
    figure = temporal_figure(paired["data"]["temporal"], None)
    tepe, residual = figure.axes
    assert tepe.get_ylabel() == "tepe [px]"
    assert "noise" in residual.get_ylabel()
    assert "temporal noise, no GT" in residual.get_title(loc="left")
    assert len(tepe.lines) == len(residual.lines) == len(NOISY_BIASED)
    block = paired["data"]["temporal"]["sequences"]["drive"]
    for line, method in zip(tepe.lines, NOISY_BIASED, strict=True):
        assert list(line.get_ydata()) == [v for _, v in block["tepe_series"][method]["values"]]
    assert NOISE_NOTE.startswith("ego-motion residual")


def test_browser_shows_the_summarys_numbers(
    browser: Any,  # noqa: F811
    paired: dict[str, Any],
) -> None:
    (sequence,) = paired["summary"]["sequences"]
    page, errors = open_report(browser, paired["out"] / "report.html")
    state = page.evaluate("window.dispevalTemporal()")
    assert state["recorded"]
    shown = state["sequences"]["drive"]
    block = paired["data"]["temporal"]["sequences"]["drive"]
    expected_tepe = [
        [m, c, e["pairs"], v["n_pair"], *(v[q] for q in block["tepe_measures"])]
        for m, e in sequence["temporal"].items()
        for c, v in e["criteria"].items()
    ]
    expected_residual = [
        [m, c, e["pairs"], v["n_residual"], *(v[q] for q in block["residual_columns"])]
        for m, e in sequence["egomotion"].items()
        for c, v in e["criteria"].items()
    ]
    assert shown["tepe"] == expected_tepe
    assert shown["residual"] == expected_residual
    view = page.locator("#temporal-view")
    assert "Temporal consistency" in view.locator("h2").text_content()
    assert page.locator("#temporal-tepe-drive tbody tr").count() == len(expected_tepe)
    assert page.locator("#temporal-residual-drive tbody tr").count() == len(expected_residual)
    for table, expected in (("tepe", expected_tepe), ("residual", expected_residual)):
        cells = page.eval_on_selector_all(
            f"#temporal-{table}-drive tbody tr",
            "rows => rows.map(r => Array.from(r.cells).map(c => c.textContent))",
        )
        for row, values in zip(cells, expected, strict=True):
            assert row[:2] == values[:2]
            for text, value in zip(row[2:], values[2:], strict=True):  # fmt: 4 or 5 digits
                assert float(text) == pytest.approx(value, rel=5e-4, abs=1e-12), (row, values)
    assert "noise, not accuracy" in page.text_content("#temporal-residual-drive thead")
    assert page.locator("#temporal-view polyline.tepe-line").count() == len(NOISY_BIASED)
    assert page.locator("#temporal-view polyline.residual-line").count() == len(NOISY_BIASED)
    assert not errors
    page.close()
    old, errors = open_report(browser, paired["old"] / "report.html")
    assert old.locator("#temporal-view").count() == 0
    assert old.evaluate("window.dispevalTemporal()")["recorded"] is False
    assert not errors
    old.close()
