"""Tests of the HTML report (dispeval_ros.report) and ``dispeval report``.

Python side: the report data round-trips the database numbers exactly, the default selection
is what the summary compares, the HTML is self-contained and escapes names, figures are PNGs.

Browser side: the report is opened from disk in Debian's chromium through Playwright (no
browser download) with every non-file request aborted; the in-browser models must give
exactly the Python results (``evaluate_models`` on the matrix built from the database) for
many random selections and through the real controls, with no console error, and a method
called ``<img src=x onerror=alert(1)>`` shown as text. Where neither a system chromium nor
Playwright is available the browser tests skip; ``DISPEVAL_REQUIRE_BROWSER=1`` (set by
``.ci/run``) makes that a failure. A 100-method × 1000-frame database must give a report
under 20 MB that re-renders within 1 s after a control change.
"""

from __future__ import annotations

import html.parser
import json
import os
import random
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dispeval_ros.core import Scores, evaluate_models
from dispeval_ros.core import kernels as k
from dispeval_ros.core.measures import SEQUENCE_MEASURES, SUM_FIELDS, thresholds_for
from dispeval_ros.io.store import FrameScores, MatchCounts, Problem, ResultsStore
from dispeval_ros.report import data as report_data
from dispeval_ros.report.data import (
    Selection,
    build_report_data,
    decode_arrays,
    default_selection,
    evaluate_selection,
    measure_recipe,
    recipe_values,
    skipped_pairs,
)
from dispeval_ros.report.html import write_report
from dispeval_ros.summary import summarize

XSS = "<img src=x onerror=alert(1)>"
SCRIPT_END = "</script><script>alert(2)</script>"
METHODS = (
    "sgbm",
    XSS,
    "bm",
    SCRIPT_END,
    "dup_1",
    "dup_2",
    "dropper",
    'a & b "quoted"',
    "__proto__",
    "ref",
    "sgbm $x_1$ (not mathtext)",
)
SEQUENCES = {"drive-a": 30, "drive <b>b</b>": 20}
CRITERIA = ("occluded", "boundary", "interior", "nonocc")
OVERLAPPING = ("nonocc",)
MEASURES = (*SEQUENCE_MEASURES, "a50", "a90")
CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
RANDOM_SELECTIONS = 50


# ------------------------------------------------------------------------------ databases


def synthetic_sums(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Random but valid accumulator rows (shape + (fields,)); ``n`` shared along axis -1."""
    fields = np.zeros((*shape, len(SUM_FIELDS)))
    n = rng.integers(200, 60_000, shape[:-1])[..., None] * np.ones(shape)
    valid = np.floor(n * rng.uniform(0.4, 1.0, shape))
    mean = rng.gamma(2.0, 0.6, shape)
    sum_e = n * mean * rng.uniform(0.9, 1.1, shape)
    sum_rel = sum_e / rng.uniform(10.0, 60.0, shape)
    bad = [np.floor(n * np.clip(rng.beta(2.0, 4.0, shape), 0, 1))]  # δ = 1
    bad_half = np.minimum(n, bad[0] + np.floor((n - bad[0]) * rng.uniform(0, 0.5, shape)))
    bad_2 = np.floor(bad[0] * rng.uniform(0.3, 0.9, shape))
    bad_4 = np.floor(bad_2 * rng.uniform(0.2, 0.9, shape))
    fields[..., 0] = n
    fields[..., 1] = valid
    fields[..., 2] = n
    fields[..., 3] = sum_e
    fields[..., 4] = sum_e**2 / n * rng.uniform(1.2, 4.0, shape)
    fields[..., 5] = sum_rel
    fields[..., 6] = sum_e * rng.uniform(50.0, 500.0, shape)
    fields[..., 7] = sum_rel * rng.uniform(0.3, 0.9, shape)
    fields[..., 8] = np.floor(bad_2 * rng.uniform(0.5, 1.0, shape))
    fields[..., 9] = bad[0]
    fields[..., 10] = bad_half
    fields[..., 11] = bad_2
    fields[..., 12] = bad_4
    return fields


def make_small_store(directory: Path, seed: int = 7) -> Path:
    """Two sequences, ten methods (hostile names, duplicates, a dropper), four criteria."""
    rng = np.random.default_rng(seed)
    thresholds = thresholds_for(MEASURES, 1.0)
    with ResultsStore.create(directory, {"methods": list(METHODS), "seed": seed}) as store:
        for s, (sequence, frames) in enumerate(SEQUENCES.items()):
            sums = synthetic_sums(rng, (frames, len(CRITERIA), len(METHODS)))
            sums[:, :, METHODS.index("dup_2")] = sums[:, :, METHODS.index("dup_1")]
            sums[3, 1, 2, 2] = 0.0  # bm: no evaluated point there, so its means are NaN
            # coarse values on one method so that ties in ranks and sums happen
            sums[:, :, METHODS.index("ref"), 3:8] = np.round(sums[:, :, 0, 3:8], -3)
            rows: list[FrameScores] = []
            problems: list[Problem] = []
            for f in range(frames):
                stamp = 1_700_000_000_000_000_000 + s * 10**12 + f * 100_000_000
                # no boundary on every 7th frame (a frame without discontinuities)
                criteria = [c for c in CRITERIA if not (c == "boundary" and f % 7 == 3)]
                for m, method in enumerate(METHODS):
                    if method == "dropper" and f % 6 == 2:
                        continue
                    if method == "bm" and f == 5:
                        problems.append(Problem(sequence, stamp, method, f"{XSS} failed"))
                        continue
                    index = [CRITERIA.index(c) for c in criteria]
                    quantiles = {
                        c: {"a50": float(sums[f, i, m, 3] / sums[f, i, m, 0]), "a90": 2.5}
                        for c, i in zip(criteria, index, strict=True)
                    }
                    scores = Scores(
                        criteria=tuple(criteria),
                        measures=MEASURES,
                        sums=np.ascontiguousarray(sums[f, index, m, :]),
                        thresholds=thresholds,
                        quantiles=quantiles,
                        overlapping=OVERLAPPING,
                    )
                    rows.append(FrameScores(sequence, stamp, method, scores))
            counts = {m: MatchCounts(frames, 0, 5 if m == "dropper" else 0, 0) for m in METHODS}
            half = len(rows) // 2
            store.add_unit(sequence, "0", rows[:half], problems, counts)
            store.add_unit(sequence, "1", rows[half:])
    return directory


def make_large_store(directory: Path, frames: int = 1000, methods: int = 100) -> Path:
    """A realistic large run: 100 methods × 1000 frames × the 3 visibility criteria."""
    rng = np.random.default_rng(3)
    criteria = ("occluded", "boundary", "interior")
    thresholds = thresholds_for(SEQUENCE_MEASURES, 1.0)
    names = [f"method_{i:03d}" for i in range(methods)]
    sums = synthetic_sums(rng, (frames, len(criteria), methods))
    with ResultsStore.create(directory, {"synthetic": True}) as store:
        for unit in range(0, frames, 100):
            rows = []
            for f in range(unit, min(frames, unit + 100)):
                stamp = 1_700_000_000_000_000_000 + f * 50_000_000
                for m, name in enumerate(names):
                    if m % 17 == 5 and f % 97 == 11:  # a few dropped frames
                        continue
                    scores = Scores(
                        criteria, SEQUENCE_MEASURES, np.ascontiguousarray(sums[f, :, m]), thresholds
                    )
                    rows.append(FrameScores("long-drive", stamp, name, scores))
            store.add_unit("long-drive", f"{unit:06d}", rows)
    return directory


GT_AND_FREE = ("all", "interior", "gtfree:all", "gtfree:textured")
GT_AND_FREE_MEASURES = ("bmp", "mae", "vpe", "density")


def make_gt_and_free_store(directory: Path) -> Path:
    """One sequence, four methods, GT criteria beside ``gtfree:`` ones (vpe sums on those)."""
    rng = np.random.default_rng(11)
    thresholds = thresholds_for(GT_AND_FREE_MEASURES, 1.0)
    methods = ("sgbm", "bm", "elas", "ref")
    with ResultsStore.create(directory, {"methods": list(methods)}) as store:
        sums = synthetic_sums(rng, (8, len(GT_AND_FREE), len(methods)))
        free = sums[:, 2:]  # no ground truth there: no evaluated point, vpe terms instead
        free[..., 2:] = 0.0
        free[..., k.FIELD_N_VPE] = np.floor(free[..., k.FIELD_VALID] * 0.9)
        free[..., k.FIELD_SUM_VPE] = free[..., k.FIELD_N_VPE] * rng.uniform(3, 12, free.shape[:-1])
        rows = [
            FrameScores(
                "drive",
                1_700_000_000_000_000_000 + f * 100_000_000,
                method,
                Scores(GT_AND_FREE, GT_AND_FREE_MEASURES, sums[f, :, m].copy(), thresholds),
            )
            for f in range(sums.shape[0])
            for m, method in enumerate(methods)
        ]
        store.add_unit("drive", "0", rows)
    return directory


@pytest.fixture(scope="module")
def small_results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_small_store(tmp_path_factory.mktemp("small"))


@pytest.fixture(scope="module")
def small_report(small_results: Path) -> tuple[Path, dict[str, Any]]:
    with ResultsStore.open(small_results) as store:
        data = build_report_data(store, title="small <test> & report")
    path = small_results / "report.html"
    write_report(data, path)
    return path, data


# ------------------------------------------------------------------------------ python side


def test_report_data_round_trips_the_database_exactly(
    small_results: Path, small_report: tuple[Path, dict[str, Any]]
) -> None:
    _, data = small_report
    arrays = decode_arrays(data)
    with ResultsStore.open(small_results) as store:
        assert data["methods"] == store.methods() == list(METHODS)
        assert [c["name"] for c in data["criteria"]] == store.criteria()
        assert [c["name"] for c in data["criteria"] if c["overlapping"]] == ["nonocc"]
        assert [m["name"] for m in data["measures"]] == store.measures()
        frame = 0
        checked = 0
        for sequence, info in zip(store.sequences(), data["sequences"], strict=True):
            assert info["name"] == sequence
            assert info["stamps"] == [str(s) for s in store.stamps(sequence)]
            counts = store.match_counts(sequence)
            assert info["counts"] == [[m, *vars(c).values()] for m, c in counts.items()]
            for stamp in store.stamps(sequence):
                stored = store.frame_scores(sequence, stamp)
                for m, method in enumerate(store.methods()):
                    scores = stored.get(method)
                    for c, criterion in enumerate(store.criteria()):
                        present = scores is not None and criterion in scores.criteria
                        assert arrays["present"][frame, c, m] == present
                        if not present:
                            assert not np.any(arrays["sums"][frame, c, m])
                            continue
                        assert scores is not None
                        row = scores.sums[scores.criteria.index(criterion)]
                        decoded = arrays["sums"][frame, c, m]
                        assert decoded.tobytes() == row.tobytes()  # bit for bit
                        for name in ("a50", "a90"):
                            assert (
                                arrays[f"stored:{name}"][frame, c, m]
                                == (scores.quantiles[criterion][name])
                            )
                        checked += 1
                frame += 1
        assert checked > 1500
        # every measure derived by the recipes equals the stored column (NaN included)
        rows = list(store.frame_rows())
        thresholds = np.asarray(data["thresholds"], dtype=float)
        stamps = [int(s) for info in data["sequences"] for s in info["stamps"]]
        frame_of = {
            (info["name"], int(s)): i
            for i, (info, s) in enumerate(
                (info, s) for info in data["sequences"] for s in info["stamps"]
            )
        }
        assert len(frame_of) == len(stamps)
        for name in store.measures():
            recipe = measure_recipe(name, np.nan_to_num(thresholds, nan=np.inf))
            values = recipe_values(recipe, arrays["sums"], arrays.get(f"stored:{name}"))
            got = np.array(
                [
                    values[
                        frame_of[row["sequence"], row["stamp"]],
                        store.criteria().index(str(row["criterion"])),
                        store.methods().index(str(row["method"])),
                    ]
                    for row in rows
                ]
            )
            expected = np.array([row[name] for row in rows], dtype=float)
            assert np.array_equal(got, expected, equal_nan=True), name
        problems = store.problems()
        assert data["problems"]["total"] == len(problems) == 2
        assert data["problems"]["shown"][0][3] == f"{XSS} failed"


def test_payload_types_are_compact(small_report: tuple[Path, dict[str, Any]]) -> None:
    _, data = small_report
    types = {c["name"]: c["type"] for c in data["arrays"]["columns"]}
    assert types["present"] == "u8"
    assert types["sum:n"] in ("u16", "u32")
    assert types["sum:sum_e"] == "f64"
    assert types["sum:bad_count_7"] == "zero"  # padding thresholds are never stored


def test_default_selection_is_what_the_summary_compares(small_results: Path) -> None:
    with ResultsStore.open(small_results) as store:
        selection = default_selection(store)
        assert selection.criteria == ("occluded", "boundary", "interior")
        assert selection.measures == ("sze", "bmpre")
        for granularity in ("sequence", "frame"):
            summary = summarize(store, granularity=granularity)
            chosen = Selection(**{**vars(selection), "granularity": granularity})
            _, names, _, models = evaluate_selection(store, chosen)
            assert names == summary.overall_objectives
            assert summary.overall is not None
            assert models is not None
            assert models.to_dict() == summary.overall.to_dict()
            for part in summary.sequences:
                one = Selection(**{**vars(chosen), "sequences": (part.sequence,)})
                _, names, _, models = evaluate_selection(store, one)
                assert names == part.objectives
                assert part.models is not None
                assert models is not None
                assert models.to_dict() == part.models.to_dict()


def test_selection_of_methods_uses_their_common_frames(small_results: Path) -> None:
    with ResultsStore.open(small_results) as store:
        everyone = report_data.common_stamps(store, "drive-a", store.methods())
        assert everyone == store.common_stamps("drive-a")
        without = [m for m in store.methods() if m not in ("dropper", "bm")]
        more = report_data.common_stamps(store, "drive-a", without)
        assert len(more) == SEQUENCES["drive-a"] > len(everyone)
        frames = {"drive-a": [0, 1, 2, 3, 99]}
        assert report_data.common_stamps(store, "drive-a", without, frames) == more[:4]


class _Tags(html.parser.HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, dict(attrs)))


def test_html_is_self_contained_and_names_are_data(
    small_report: tuple[Path, dict[str, Any]],
) -> None:
    path, data = small_report
    text = path.read_text(encoding="utf-8")
    parser = _Tags()
    parser.feed(text)
    tags = [tag for tag, _ in parser.tags]
    assert tags.count("script") == 2
    assert "img" not in tags
    assert "link" in tags
    for tag, attrs in parser.tags:
        for key in ("src", "href", "action", "data", "poster"):
            value = attrs.get(key) or ""
            assert not re.match(r"\s*(https?:)?//", value), (tag, key, value)
        if tag == "script":
            assert "src" not in attrs
        if tag == "link":
            assert attrs.get("href") == "data:,"
    assert "Content-Security-Policy" in text
    assert "default-src 'none'" in text
    script = text.split('<script type="application/json" id="dispeval-data">')[1]
    script = script.split("</script>")[0]
    assert "<" not in script
    assert ">" not in script
    assert "&" not in script
    assert json.loads(script) == json.loads(json.dumps(data))
    # hostile names are in the data only, escaped
    assert XSS not in text
    assert "onerror=alert(1)" in text
    assert text.count("</script>") == 2
    assert "small &lt;test&gt; &amp; report" in text
    js = text.split("<script>\n")[1]
    for forbidden in ("fetch(", "XMLHttpRequest", "WebSocket", "EventSource", "sendBeacon"):
        assert forbidden not in js
    assert "innerHTML" not in js
    assert "insertAdjacentHTML" not in js
    assert "eval(" not in js


def test_png_figures_are_written(small_results: Path, tmp_path: Path) -> None:
    from PIL import Image

    from dispeval_ros.report.figures import FIGURES, write_figures

    with ResultsStore.open(small_results) as store:
        paths = write_figures(store, tmp_path / "figures")
    assert [p.name for p in paths] == list(FIGURES)
    for path in paths:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        with Image.open(path) as image:
            image.verify()
        with Image.open(path) as image:
            assert image.size[0] >= 300
            assert image.size[1] >= 150


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "dispeval_ros", *args],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def test_cli_writes_the_report_and_figures(small_results: Path, tmp_path: Path) -> None:
    out = tmp_path / "r.html"
    done = run_cli(
        "report",
        str(small_results / "results.sqlite"),
        "-o",
        str(out),
        "--png",
        str(tmp_path / "png"),
    )
    assert done.returncode == 0, done.stderr
    assert f"report: {out}" in done.stdout
    assert out.stat().st_size > 10_000
    assert len(list((tmp_path / "png").glob("*.png"))) == 4


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("{missing}",), "no such file"),
        (("{results}", "--thumbnails", "-1"), "--thumbnails must be 0 or more"),
        (("{results}", "--bag", "{missing}"), "matches no sequence"),
    ],
)
def test_cli_errors_are_one_line(
    small_results: Path, tmp_path: Path, args: tuple[str, ...], message: str
) -> None:
    values = {"missing": str(tmp_path / "nothing"), "results": str(small_results)}
    done = run_cli("report", *(a.format(**values) for a in args), "-o", str(tmp_path / "x.html"))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith("dispeval report: error:"), done.stderr
    assert message in lines[0]


def test_demo_writes_the_report_with_error_maps(tmp_path: Path) -> None:
    done = run_cli("demo", "--out", str(tmp_path / "demo"))
    assert done.returncode == 0, done.stderr
    report = tmp_path / "demo" / "report.html"
    assert f"report: {report}" in done.stdout
    text = report.read_text(encoding="utf-8")
    payload = text.split('id="dispeval-data">')[1].split("</script>")[0]
    data = json.loads(payload)
    thumbnails = data["thumbnails"]
    assert len(thumbnails["frames"]) == 4
    for frame in thumbnails["frames"]:
        assert [m for m, _ in frame["images"]] == data["methods"]
        for _, uri in frame["images"]:
            assert uri.startswith("data:image/png;base64,")
    # the same through `dispeval report --bag` (the demo records its topics)
    bag = data["sequences"][0]["source"]
    again = run_cli(
        "report",
        str(tmp_path / "demo"),
        "-o",
        str(tmp_path / "r.html"),
        "--bag",
        bag,
        "--thumbnails",
        "2",
    )
    assert again.returncode == 0, again.stderr


# ------------------------------------------------------------------------------ browser side


def _browser_available() -> str | None:
    """Why the browser tests cannot run, or None."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "the playwright Python package is not installed"
    if CHROMIUM.is_file():
        return None
    return f"no chromium at {CHROMIUM} (apt-get install chromium)"


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """One headless chromium context with the network disabled (file:// only)."""
    reason = _browser_available()
    if reason is not None:
        if os.environ.get("DISPEVAL_REQUIRE_BROWSER") == "1":
            pytest.fail(f"DISPEVAL_REQUIRE_BROWSER=1 but {reason}")
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    profile = tempfile.mkdtemp(prefix="dispeval-chromium-")
    blocked: list[str] = []
    with sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            profile,
            executable_path=str(CHROMIUM),
            headless=True,
            args=CHROMIUM_ARGS,
            viewport={"width": 1400, "height": 1000},
            service_workers="block",
        )

        def route(route: Any) -> None:
            if route.request.url.startswith(("file://", "data:")):
                route.continue_()
            else:
                blocked.append(route.request.url)
                route.abort()

        context.route("**/*", route)
        context.set_offline(True)
        context.blocked = blocked  # type: ignore[attr-defined]
        yield context
        context.close()
    shutil.rmtree(profile, ignore_errors=True)
    assert not blocked, f"the report tried to reach the network: {blocked[:5]}"


def open_report(context: Any, path: Path) -> tuple[Any, list[str]]:
    """A page showing the report; console errors, page errors and dialogs are collected."""
    page = context.new_page()
    errors: list[str] = []
    page.on(
        "console",
        lambda m: errors.append(f"console {m.type}: {m.text}") if m.type == "error" else None,
    )
    page.on("pageerror", lambda e: errors.append(f"page error: {e}"))

    def dialog(d: Any) -> None:
        errors.append(f"dialog: {d.message}")
        d.dismiss()

    page.on("dialog", dialog)
    page.goto(path.resolve().as_uri())
    page.wait_for_selector('body[data-ready="1"], body[data-failed="1"]', timeout=120_000)
    assert page.evaluate("document.body.dataset.failed") is None, page.text_content("#app")
    return page, errors


def random_selection(rng: random.Random, store: ResultsStore) -> Selection:
    sequences = store.sequences()
    chosen = rng.sample(sequences, rng.randint(1, len(sequences)))
    frames: dict[str, list[int]] | None = None
    if rng.random() < 0.5:
        frames = {}
        for sequence in chosen:
            count = len(store.stamps(sequence))
            if rng.random() < 0.5:
                start = rng.randrange(count)
                frames[sequence] = list(range(start, min(count, start + rng.randint(1, 12))))
            elif rng.random() < 0.5:
                frames[sequence] = sorted(rng.sample(range(count), rng.randint(1, 8)))
    methods = store.methods()
    return Selection(
        sequences=tuple(chosen),
        criteria=tuple(rng.sample(store.criteria(), rng.randint(1, len(store.criteria())))),
        measures=tuple(rng.sample(store.measures(), rng.randint(1, 3))),
        methods=tuple(rng.sample(methods, rng.choice([1, 2, 3, 5, 8, len(methods)]))),
        granularity=rng.choice(["sequence", "frame"]),
        frames=frames,
    )


def python_models(store: ResultsStore, selection: Selection) -> dict[str, Any]:
    methods, names, matrix, models = evaluate_selection(store, selection)
    return {
        "methods": methods,
        "objectives": names,
        "matrix": matrix,
        "models": None if models is None else models.to_dict(),
    }


def same_result(js: dict[str, Any], py: dict[str, Any]) -> list[str]:
    """What differs between the browser's and Python's results (empty: identical)."""
    differences = []
    for key in ("methods", "objectives", "models"):
        if js[key] != py[key]:
            differences.append(key)
    values = [[float(v) for v in row] for row in js["matrix"]]  # "NaN" strings included
    matrix = np.array(values, dtype=np.float64).reshape(py["matrix"].shape)
    if not np.array_equal(matrix, py["matrix"], equal_nan=True):
        differences.append("matrix")
    return differences


def test_browser_models_equal_python_for_random_selections(
    browser: Any,
    small_results: Path,
    small_report: tuple[Path, dict[str, Any]],
    capsys: pytest.CaptureFixture[str],
) -> None:
    page, errors = open_report(browser, small_report[0])
    rng = random.Random(2024)
    matched = 0
    with ResultsStore.open(small_results) as store:
        selections = [random_selection(rng, store) for _ in range(RANDOM_SELECTIONS)]
        # the corner cases too: one method, one frame, everything
        selections.append(Selection(**{**vars(default_selection(store)), "methods": ("ref",)}))
        selections.append(
            Selection(**{**vars(default_selection(store)), "frames": {"drive-a": [4]}})
        )
        everything = default_selection(store)
        selections.append(
            Selection(
                sequences=everything.sequences,
                criteria=tuple(store.criteria()),
                measures=tuple(store.measures()),
                methods=everything.methods,
                granularity="frame",
            )
        )
        # as JSON text: a method called "__proto__" must survive as a key
        results = [
            json.loads(text)
            for text in page.evaluate(
                "selections => selections.map(s => window.dispevalModelsJSON(s, true))",
                [s.to_dict() for s in selections],
            )
        ]
        failures = []
        with_models = 0
        for selection, js in zip(selections, results, strict=True):
            py = python_models(store, selection)
            differences = same_result(js, py)
            if differences:
                failures.append((selection.to_dict(), differences))
            else:
                matched += 1
                with_models += py["models"] is not None
    with capsys.disabled():
        print(
            f"\n[report] in-browser models equal to Python on {matched} of {len(selections)} "
            f"selections ({with_models} with models; {RANDOM_SELECTIONS} random)"
        )
    assert not failures, failures[:3]
    assert with_models >= RANDOM_SELECTIONS - 5
    assert not errors, errors
    page.close()


def displayed(page: Any) -> dict[str, Any]:
    """What the page shows: table rows (method, group, u1, u2, reduced, rank) and texts."""
    return page.evaluate(
        """() => ({
        rows: Array.from(document.querySelectorAll('#group-table tbody tr')).map(tr => ({
            method: tr.querySelector('.c-method').textContent,
            group: Number(tr.querySelector('.c-group').textContent),
            reduced: tr.querySelector('.c-reduced').textContent === 'yes',
            u1: tr.dataset.u1 === undefined ? null : Number(tr.dataset.u1),
            u2: tr.dataset.u2 === undefined ? null : Number(tr.dataset.u2),
            rank: Number(tr.dataset.rank),
        })),
        interpretation: document.getElementById('interpretation').textContent,
        middlebury: document.getElementById('middlebury-text').textContent,
        selection: window.dispevalSelection(),
        images: document.querySelectorAll('img').length,
    })"""
    )


def check_display(
    shown: dict[str, Any], store: ResultsStore, selection: Selection, model: str
) -> None:
    methods, _, matrix, models = evaluate_selection(store, selection)
    assert models is not None
    expected = evaluate_models(methods, matrix)
    assert shown["interpretation"] == expected.interpretation
    position = {m: i for i, m in enumerate(methods)}
    if model == "middlebury":
        order = sorted(methods, key=lambda m: (expected.middlebury[m], position[m]))
        assert shown["middlebury"].startswith("Middlebury model")
    else:
        order = sorted(
            methods, key=lambda m: (expected.groups[m], expected.middlebury[m], position[m])
        )
        assert shown["middlebury"] == ""
    assert [row["method"] for row in shown["rows"]] == order
    for row in shown["rows"]:
        name = row["method"]
        assert row["group"] == expected.groups[name]
        assert row["reduced"] == (name in expected.reduced)
        assert row["rank"] == expected.middlebury[name]
        pair = expected.reduction.get(name)
        assert (row["u1"], row["u2"]) == ((pair["u1"], pair["u2"]) if pair else (None, None))


def test_browser_controls_recompute_the_models(
    browser: Any,
    small_results: Path,
    small_report: tuple[Path, dict[str, Any]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    page, errors = open_report(browser, small_report[0])
    with ResultsStore.open(small_results) as store:
        selection = default_selection(store)
        check_display(displayed(page), store, selection, "astar")

        def click(kind: str, index: int) -> None:
            page.locator(f'input[data-kind="{kind}"][data-index="{index}"]').click()

        steps: list[tuple[str, Any]] = [
            ("criterion", 3),  # add the overlapping nonocc
            ("measure", store.measures().index("mae")),
            ("criterion", 0),  # drop occluded
            ("method", 2),  # drop bm
            ("model", "middlebury"),
            ("granularity", "frame"),
            ("method", 6),  # drop the dropper
            ("measure", store.measures().index("density")),
            ("model", "astar"),
            ("sequence", 1),
        ]
        model = "astar"
        criteria = list(selection.criteria)
        measures = list(selection.measures)
        methods = list(selection.methods)
        sequences = list(selection.sequences)
        granularity = "sequence"
        for kind, value in steps:
            if kind in ("model", "granularity"):
                page.locator(f'input[name="{kind}"][value="{value}"]').check()
                if kind == "model":
                    model = value
                else:
                    granularity = value
            else:
                click(kind, value)
                lists = {
                    "criterion": (criteria, store.criteria()),
                    "measure": (measures, store.measures()),
                    "method": (methods, store.methods()),
                    "sequence": (sequences, store.sequences()),
                }
                chosen, names = lists[kind]
                name = names[value]
                if name in chosen:
                    chosen.remove(name)
                else:
                    chosen.append(name)
            expected = Selection(
                tuple(sequences), tuple(criteria), tuple(measures), tuple(methods), granularity
            )
            shown = displayed(page)
            assert set(shown["selection"]["methods"]) == set(methods)
            assert set(shown["selection"]["criteria"]) == set(criteria)
            assert shown["selection"]["model"] == model
            check_display(shown, store, expected, model)
        # a frame range through the number inputs
        page.locator('input[data-kind="frame-to"][data-index="0"]').fill("10")
        page.locator('input[data-kind="frame-to"][data-index="0"]').dispatch_event("change")
        expected = Selection(
            tuple(sequences),
            tuple(criteria),
            tuple(measures),
            tuple(methods),
            granularity,
            frames={"drive-a": list(range(10))},
        )
        check_display(displayed(page), store, expected, model)
    # the hostile name is text, and no element was made from it
    shown = displayed(page)
    assert XSS in [row["method"] for row in shown["rows"]]
    assert SCRIPT_END in [row["method"] for row in shown["rows"]]
    assert shown["images"] == 0
    assert page.evaluate("document.querySelectorAll('b').length") == 0
    labels = page.evaluate(
        "Array.from(document.querySelectorAll('#controls label span')).map(s => s.textContent)"
    )
    assert XSS in labels
    assert "drive <b>b</b>" in labels
    shot = tmp_path / "report.png"
    page.screenshot(path=str(shot), full_page=True)
    assert shot.read_bytes()[:4] == b"\x89PNG"
    with capsys.disabled():
        print(f"\n[report] screenshot: {shot}")
    assert not errors, errors
    page.close()


def test_browser_objectives_only_from_pairs_that_apply(browser: Any, tmp_path: Path) -> None:
    """GT measures on gtfree: criteria (and vpe on GT criteria) give no objective, never NaN
    ones, in the page as in Python, and the page says which pairs it skipped."""
    results = make_gt_and_free_store(tmp_path / "free")
    with ResultsStore.open(results) as store:
        write_report(build_report_data(store), tmp_path / "report.html")
        page, errors = open_report(browser, tmp_path / "report.html")
        mixed = Selection(
            ("drive",), GT_AND_FREE, ("bmp", "vpe", "density"), tuple(store.methods())
        )
        for granularity in ("sequence", "frame"):
            selection = Selection(**{**vars(mixed), "granularity": granularity})
            js = json.loads(
                page.evaluate("s => window.dispevalModelsJSON(s, true)", selection.to_dict())
            )
            py = python_models(store, selection)
            assert not same_result(js, py), same_result(js, py)
            assert py["models"] is not None
            assert not np.isnan(py["matrix"]).any()
            assert (
                js["skipped"]
                == skipped_pairs(selection)
                == ["all/vpe", "interior/vpe", "gtfree:all/bmp", "gtfree:textured/bmp"]
            )
            labels = {name.split(" @")[0] for name in py["objectives"]}
            assert labels == {
                "all/bmp",
                "all/density",
                "interior/bmp",
                "interior/density",
                "gtfree:all/vpe",
                "gtfree:all/density",
                "gtfree:textured/vpe",
                "gtfree:textured/density",
            }
        # through the controls: add the gtfree: criteria and vpe to the default selection
        default = default_selection(store)
        assert default.criteria == ("all", "interior")

        def toggle(criteria: tuple[str, ...], measure: str) -> None:
            for name in criteria:
                index = store.criteria().index(name)
                page.locator(f'input[data-kind="criterion"][data-index="{index}"]').click()
            index = store.measures().index(measure)
            page.locator(f'input[data-kind="measure"][data-index="{index}"]').click()

        toggle(("gtfree:all", "gtfree:textured"), "vpe")
        chosen = Selection(("drive",), GT_AND_FREE, (*default.measures, "vpe"), default.methods)
        check_display(displayed(page), store, chosen, "astar")
        warnings = page.text_content("#warnings") or ""
        # the default measures follow the rule of the objectives (bmp and mae, not density)
        assert default.measures == ("bmp", "mae")
        assert "Skipped 6 criterion/measure pairs that do not apply" in warnings
        for pair in skipped_pairs(chosen):
            assert pair in warnings
        assert "NaN" not in (page.text_content("#objective-names") or "")
        # the totals of the plotted measure (bmp) only on the criteria it applies to
        assert page.evaluate("document.getElementById('bars').children.length") == 2
        # the per-frame curves: a measure on a criterion it is not defined on plots nothing
        # (no red "undefined" marks) and says why; on a criterion it applies to, it plots
        page.select_option("#plot-measure", str(store.measures().index("vpe")))
        page.select_option("#plot-criterion", str(store.criteria().index("all")))
        note = page.text_content("#curves-note") or ""
        assert "vpe is not defined on criterion all" in note
        assert "red marks" not in note
        page.select_option("#plot-criterion", str(store.criteria().index("gtfree:all")))
        note = page.text_content("#curves-note") or ""
        assert note.startswith("vpe [grey levels] of criterion gtfree:all")  # unit: registry
        assert "0 red marks" in note
        # only GT measures on only gtfree: criteria: no objective, and the page says why
        toggle(("all", "interior"), "vpe")
        status = page.text_content("#status") or ""
        assert "none of the selected measures applies to the selected criteria" in status
        assert not errors, errors
        page.close()


def test_browser_shows_the_demo_report(
    browser: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    done = run_cli("demo", "--out", str(tmp_path / "demo"))
    assert done.returncode == 0, done.stderr
    page, errors = open_report(browser, tmp_path / "demo" / "report.html")
    assert (
        page.evaluate("document.querySelectorAll('#thumbnails img').length") == 17
    )  # 4×4 + legend
    assert page.evaluate(
        "Array.from(document.querySelectorAll('#thumbnails img'))"
        ".every(i => i.complete && i.naturalWidth > 0)"
    )
    shot = tmp_path / "demo-report.png"
    page.screenshot(path=str(shot), full_page=True)
    with capsys.disabled():
        print(f"\n[report] demo screenshot: {shot}")
    assert not errors, errors
    page.close()


# ------------------------------------------------------------------------------ large report


@pytest.mark.slow
def test_large_report_is_small_and_fast(
    browser: Any, tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path_factory.mktemp("large")
    started = time.perf_counter()
    make_large_store(folder)
    built = time.perf_counter()
    with ResultsStore.open(folder) as store:
        data = build_report_data(store)
    path = folder / "report.html"
    size = write_report(data, path)
    written = time.perf_counter()
    page, errors = open_report(browser, path)
    loaded = time.perf_counter()
    measure = """async ([kind, index]) => {
        const box = document.querySelector(`input[data-kind="${kind}"][data-index="${index}"]`);
        const t0 = performance.now();
        box.click();
        await new Promise(r => requestAnimationFrame(() => setTimeout(r, 0)));
        return [performance.now() - t0, window.dispevalTiming.last];
    }"""
    timings = {
        "method": page.evaluate(measure, ["method", 7]),
        "criterion": page.evaluate(measure, ["criterion", 1]),
        "measure": page.evaluate(measure, ["measure", 2]),
    }
    page.locator('input[name="granularity"][value="frame"]').check()
    timings["per-frame objectives, method"] = page.evaluate(measure, ["method", 7])
    timings["per-frame objectives, measure"] = page.evaluate(measure, ["measure", 2])
    rows = page.evaluate("document.querySelectorAll('#group-table tbody tr').length")
    with capsys.disabled():
        print(
            f"\n[report] 100 methods × 1000 frames × 3 criteria: report {size / 1e6:.2f} MB "
            f"(database {built - started:.1f} s, report {written - built:.1f} s, "
            f"browser load {loaded - written:.1f} s); control change → re-rendered: "
            + ", ".join(f"{k} {v[0]:.0f} ms (render {v[1]:.0f} ms)" for k, v in timings.items())
        )
    # The timings are printed, never asserted: a loaded machine would fail them at random.
    assert size < 20_000_000
    assert rows == 100
    assert all(elapsed > 0 for elapsed, _ in timings.values())  # every change re-rendered
    assert not errors, errors
    page.close()
