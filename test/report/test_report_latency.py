"""The report's latency view: latency against accuracy, the first A* group, the delay per frame.

On the bag of test/offline/test_latency.py where the fastest method (``rough``) is the least
accurate (:func:`bag_support.fast_rough_bag`), ranked on ``sze bmpre latency_p95``: the report
plots summary.json's numbers, rings the summary's first A* group, and says "latency not
recorded" for a database written before arrival times were.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bag_support import NOISE, as_written_before, fast_rough_bag
from test_report import browser, make_small_store, open_report  # noqa: F401  (browser fixture)

from dispeval_ros.cli.main import main
from dispeval_ros.core.measures import measure_unit
from dispeval_ros.core.models import evaluate_models
from dispeval_ros.core.objectives import split_timing_measures, timing_objectives
from dispeval_ros.core.timing import TIMING_MEASURES
from dispeval_ros.io.store import TIMING_TABLE, ResultsStore
from dispeval_ros.offline.make_bag import method_latency_ns
from dispeval_ros.report.data import Selection, build_report_data, selection_objectives
from dispeval_ros.report.figures import FIGURES, write_figures
from dispeval_ros.report.latency import latency_data
from dispeval_ros.report.latency_figures import (
    LATENCY_FIGURES,
    delays_figure,
    front_2d,
    latency_accuracy_figure,
    latency_panels,
)
from dispeval_ros.summary import sequence_timing

FRAMES = 12
OBJECTIVES = ["sze", "bmpre", "latency_p95"]


def page_data(html: Path) -> dict[str, Any]:
    payload = html.read_text("utf-8").split('id="dispeval-data">')[1].split("</script>")[0]
    return json.loads(payload)


@pytest.fixture(scope="module")
def ranked(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The bag run on (sze, bmpre, latency_p95), its report (page and PNGs), an older copy."""
    root = tmp_path_factory.mktemp("report_latency")
    _, args, orders = fast_rough_bag(root, FRAMES)
    out = root / "res"
    assert main([*args, "--objective-measures", *OBJECTIVES]) == 0
    assert main(["report", str(out), "--png", str(root / "png"), "--quiet"]) == 0
    old = root / "old"
    as_written_before(out, old, TIMING_TABLE)  # as written before arrival times were
    assert main(["report", str(old), "--png", str(root / "old_png"), "--quiet"]) == 0
    return {
        "root": root,
        "out": out,
        "old": old,
        "orders": orders,
        "summary": json.loads((out / "summary.json").read_text()),
        "data": page_data(out / "report.html"),
        "old_data": page_data(old / "report.html"),
    }


def test_the_plotted_latency_is_the_summarys(ranked: dict[str, Any]) -> None:
    (sequence,) = ranked["summary"]["sequences"]
    latency = ranked["data"]["latency"]
    assert latency["recorded"]
    assert latency["default"] == "latency_p95"
    block = latency["sequences"][sequence["sequence"]]
    assert block["methods"] == list(NOISE)
    for method in NOISE:
        for name in TIMING_MEASURES:
            assert block["values"][method][name] == sequence["latency"][method][name], name
        expected = method_latency_ns(ranked["orders"][method]) / 1e6  # make-bag's recorded delay
        assert block["delays"][method] == [[frame, expected] for frame in range(FRAMES)]
    assert [m["label"] for m in latency["measures"]][:2] == [
        "latency_median [ms]",
        "latency_p95 [ms]",
    ]


def test_the_first_group_is_the_summarys_and_holds_the_fastest_and_the_most_accurate(
    ranked: dict[str, Any],
) -> None:
    (sequence,) = ranked["summary"]["sequences"]
    assert "latency_p95 @drive" in sequence["objectives"]
    groups = sequence["models"]["groups"]
    block = ranked["data"]["latency"]["sequences"]["drive"]
    assert ranked["data"]["latency"]["objective_measures"] == OBJECTIVES
    assert block["objectives"] == sequence["objectives"]
    assert block["groups"] == groups
    assert sorted(block["first_group"]) == sorted(m for m, g in groups.items() if g == 1)
    p95 = {m: sequence["latency"][m]["latency_p95"] for m in NOISE}
    sze = {m: sequence["scores"][m]["all"]["sze"] for m in NOISE}
    fastest, most_accurate = min(p95, key=p95.__getitem__), min(sze, key=sze.__getitem__)
    assert (fastest, most_accurate) == ("rough", "fine")
    assert set(block["first_group"]) == {fastest, most_accurate}
    with ResultsStore.open(ranked["out"]) as store:  # on accuracy alone rough is dominated
        alone = build_report_data(store, objective_measures=["sze", "bmpre"])["latency"]
    assert alone["sequences"]["drive"]["first_group"] == ["fine"]


def test_an_older_database_says_latency_not_recorded(ranked: dict[str, Any]) -> None:
    latency = ranked["old_data"]["latency"]
    assert latency["recorded"] is False
    assert latency["not_recorded"].startswith("latency not recorded")
    assert "sequences" not in latency
    assert sorted(p.name for p in (ranked["root"] / "old_png").iterdir()) == sorted(FIGURES)


def test_results_without_arrivals_say_latency_not_recorded(tmp_path: Path) -> None:
    """A database with the timing table but no arrival in it (as ``eval --out`` writes one)."""
    with ResultsStore.open(make_small_store(tmp_path)) as store:
        assert store.records_timing()
        assert all(not store.timing(s) for s in store.sequences())
        assert latency_data(store)["recorded"] is False


def test_the_png_figures_have_units_on_both_axes(ranked: dict[str, Any]) -> None:
    written = {p.name for p in (ranked["root"] / "png").iterdir()}
    assert written == {*FIGURES, *LATENCY_FIGURES}
    with ResultsStore.open(ranked["out"]) as store:
        x_name, panels = latency_panels(store, ranked["data"]["latency"], "all", "sze")
        assert [p.name for p in write_figures(store, ranked["root"] / "again")][-2:] == list(
            LATENCY_FIGURES
        )
    (panel,) = panels
    sequence = ranked["summary"]["sequences"][0]
    assert panel["y"] == [sequence["scores"][m]["all"]["sze"] for m in NOISE]
    figure = latency_accuracy_figure(panels, x_name, "sze", measure_unit("sze", False), None)
    (axes,) = figure.axes
    assert axes.get_xlabel() == "latency_p95 [ms]"
    assert axes.get_ylabel() == f"sze [{measure_unit('sze', False)}]" == "sze [m]"
    (delays,) = delays_figure(panels, None).axes
    figure.canvas.draw()
    delays.figure.canvas.draw()
    assert delays.get_xlabel() == "frame"
    assert delays.get_ylabel() == "delay [ms]"
    assert delays.get_xlim()[0] <= 1
    assert delays.get_xlim()[1] >= FRAMES
    short = {"sequence": "two", "delays": {"a": [[0, 1.0], [1, 2.5]]}}  # a plain axis: 1.2, 1.4…
    for axes in (delays, *delays_figure([short], None).axes):
        axes.figure.canvas.draw()
        ticks = [t for t in axes.get_xticks() if axes.get_xlim()[0] <= t <= axes.get_xlim()[1]]
        assert len(ticks) >= 2
        assert all(float(t).is_integer() for t in ticks), ticks


def test_the_front_of_two_axes() -> None:
    points = [(1.0, 5.0), (2.0, 3.0), (3.0, 4.0), (4.0, 1.0), (float("nan"), 0.0), (1.0, 6.0)]
    assert front_2d(points) == [0, 1, 3]
    assert front_2d(points, y_higher=True) == [5]
    assert front_2d(points, x_higher=True) == [3]


def test_browser_plots_latency_against_accuracy(
    browser: Any,  # noqa: F811
    ranked: dict[str, Any],
) -> None:
    page, errors = open_report(browser, ranked["out"] / "report.html")
    state = page.evaluate("window.dispevalLatency()")
    drive = state["sequences"]["drive"]
    sequence = ranked["summary"]["sequences"][0]
    assert drive["x"] == "latency_p95"
    assert {p["name"]: p["x"] for p in drive["points"]} == {
        m: sequence["latency"][m]["latency_p95"] for m in NOISE
    }
    assert {p["name"] for p in drive["points"] if p["first"]} == {"rough", "fine"}
    assert sorted(drive["front"]) == ["fine", "rough"]
    assert page.locator("#latency-view svg.latency-chart").count() == 2
    assert page.locator("#latency-view g.first-group").count() == 2
    assert page.locator("#latency-view path.front").count() == 1
    assert page.locator("#latency-view polyline.delay-line").count() == len(NOISE)
    assert "latency_p95 [ms]" in page.text_content("#latency-view")
    page.select_option("#latency-measure", "latency_max")
    page.wait_for_function("window.dispevalLatency().sequences.drive.x === 'latency_max'")
    assert "latency_max [ms]" in page.text_content("#latency-view .x-label")
    assert not errors
    page.close()
    old, errors = open_report(browser, ranked["old"] / "report.html")
    assert old.text_content("#latency-note") == ranked["old_data"]["latency"]["not_recorded"]
    assert old.locator("#latency-view svg").count() == 0
    assert not errors
    old.close()


def test_objectives_the_models_cannot_use_leave_the_groups_out_not_the_plot(
    ranked: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    with ResultsStore.open(ranked["out"]) as store:
        latency = build_report_data(store, objective_measures=["sze", "a42"])["latency"]
    assert "a42 were not computed" in latency["problem"]
    block = latency["sequences"]["drive"]
    assert block["groups"] is None
    assert block["first_group"] == []
    assert block["values"] == ranked["data"]["latency"]["sequences"]["drive"]["values"]
    assert main(["report", str(ranked["out"]), "-o", str(ranked["root"] / "x.html"),
                 "--objective-measures", "sze", "a42"]) == 2  # fmt: skip
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "--objective-measures a42: neither stored" in line


THREE = {"rough": 3.0, "fine": 0.3, "slow": 1.0}
"""px of noise, logged in this order: ``slow`` is less accurate than ``fine`` and later, so
dominated by it (group 2) until ``fine`` is deselected; then it is incomparable with ``rough``."""


def python_first_group(store: ResultsStore, sequence: str, methods: list[str]) -> set[str]:
    """A* group 1 of summary.json's objectives on ``methods`` only, by the Python models: the
    accuracy objectives on their common frames, the timing ones of the sequence."""
    scored, timed = split_timing_measures(OBJECTIVES)
    overlapping = set(store.overlapping_criteria())
    criteria = tuple(c for c in store.criteria() if c not in overlapping)
    selection = Selection((sequence,), criteria, tuple(scored), tuple(methods))
    names, _, matrix = selection_objectives(store, selection)
    _, block = timing_objectives(sequence_timing(store, sequence), sequence, names, timed)
    models = evaluate_models(names, np.hstack([matrix, block]))
    return {m for m, group in models.groups.items() if group == 1}


def test_browser_rings_group_one_of_the_selected_methods(
    browser: Any,  # noqa: F811
    tmp_path: Path,
) -> None:
    """Deselecting a member of A* group 1 regroups the rest: the ring moves to what the
    Python models give on the remaining methods; selecting it again brings the run's back."""
    _, args, _ = fast_rough_bag(tmp_path, FRAMES, THREE)
    out = tmp_path / "res"
    assert main([*args, "--objective-measures", *OBJECTIVES]) == 0
    assert main(["report", str(out), "--quiet"]) == 0
    (sequence,) = json.loads((out / "summary.json").read_text())["sequences"]
    groups = sequence["models"]["groups"]
    assert groups == {"rough": 1, "fine": 1, "slow": 2}
    with ResultsStore.open(out) as store:
        assert python_first_group(store, "drive", list(THREE)) == {"rough", "fine"}
        expected = python_first_group(store, "drive", ["rough", "slow"])
    assert expected == {"rough", "slow"}  # the ring moves

    page, errors = open_report(browser, out / "report.html")

    def ringed() -> set[str]:
        drive = page.evaluate("window.dispevalLatency()")["sequences"]["drive"]
        return {p["name"] for p in drive["points"] if p["first"]}

    assert ringed() == {"rough", "fine"}
    fine = page.locator(f'input[data-kind="method"][data-index="{list(THREE).index("fine")}"]')
    renders = page.evaluate("Number(document.body.dataset.renders)")
    fine.uncheck()
    page.wait_for_function(f"Number(document.body.dataset.renders) > {renders}")
    assert ringed() == expected
    assert page.locator("#latency-view g.first-group").count() == 2
    assert "A* group 1 of the selected methods" in page.text_content("#latency-note")
    fine.check()
    page.wait_for_function(f"Number(document.body.dataset.renders) > {renders + 1}")
    assert ringed() == {"rough", "fine"}
    assert not errors
    page.close()
