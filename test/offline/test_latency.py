"""Latency and rate of ``dispeval bag``: per-frame delays, their summaries, and as objectives.

The bags are made by make-bag's writer, whose per-method delay is a named fact
(:func:`method_latency_ns`); the expected values are computed here from the bag's own log
times with plain Python, not with the project's timing code.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from bag_support import METHODS, bag_args, fast_rough_bag

from dispeval_ros.cli.main import main
from dispeval_ros.cli.output import WIDTH
from dispeval_ros.cli.summary import latency_text, run_summary_text
from dispeval_ros.core.objectives import timing_objectives
from dispeval_ros.core.timing import timing_of
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.io.store import TIMING_COLUMNS, TIMING_JSON, TIMING_TABLE, ResultsStore
from dispeval_ros.offline.make_bag import (
    disparity_topic,
    method_latency_ns,
    synthetic_frames,
    write_bag,
)
from dispeval_ros.summary import summarize

FRAMES = 12
MISSED = {2: (3, 7)}
"""Make-bag order → frames whose map that source leaves out (the varied bag)."""


def varied_delay(order: int, index: int) -> int | None:
    """The recorded delay plus a deterministic 0–22 ms, None for the frames it misses."""
    if index in MISSED.get(order, ()):
        return None
    return method_latency_ns(order) + ((index * 7919 + order * 104729) % 23) * 1_000_000


def make(root: Path, name: str, **options: object) -> tuple[Path, dict[str, int]]:
    """A synthetic drive bag; returns it and each method's make-bag order."""
    bag = root / name
    summary = write_bag(
        bag, synthetic_frames(FRAMES, 192, 64, 10.0, seed=4), storage="rosbag2-sqlite3", **options
    )
    return bag, {m: i for i, m in enumerate(summary["methods"])}  # type: ignore[arg-type]


def run_bag(bag: Path, out: Path, *extra: str) -> None:
    assert main(bag_args(bag, out, *extra)) == 0


def logged(bag: Path) -> dict[str, list[tuple[int, int]]]:
    """Per method, (header stamp, log time) of each of its messages, as the bag holds them."""
    found: dict[str, list[tuple[int, int]]] = {m: [] for m in METHODS}
    with BagSource(bag) as source:
        for topic, log_ns, msg in source.messages([disparity_topic(m) for m in METHODS]):
            found[topic.split("/")[2]].append((stamp_ns(msg.header), log_ns))
    return found


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, dict[str, int]]:
    root = tmp_path_factory.mktemp("latency")
    bag, orders = make(root, "drive")
    run_bag(bag, root / "res")
    return bag, root / "res", orders


@pytest.fixture(scope="module")
def varied(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, dict[str, int]]:
    root = tmp_path_factory.mktemp("varied")
    bag, orders = make(root, "drive", delay=varied_delay)
    run_bag(bag, root / "res")
    return bag, root / "res", orders


def test_the_measured_delay_is_the_recorded_one_per_frame(
    made: tuple[Path, Path, dict[str, int]],
) -> None:
    bag, out, orders = made
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        timing = store.timing(sequence)
    assert timing is not None
    assert set(timing) == set(METHODS)
    for method, entries in timing.items():
        assert len(entries) == FRAMES
        assert {entry.delay for entry in entries} == {method_latency_ns(orders[method])}
        assert sorted((e.estimate_stamp, e.arrival) for e in entries) == sorted(logged(bag)[method])
    with open(out / "frames.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0])[-len(TIMING_COLUMNS) :] == list(TIMING_COLUMNS)
    for row in rows:
        expected = method_latency_ns(orders[row["method"]])
        assert int(row["arrival"]) - int(row["estimate_stamp"]) == expected
        assert float(row["delay_ms"]) == expected / 1e6


def _percentile(values: list[float], share: float) -> float:
    """Linear interpolation between order statistics (numpy's default), from its definition."""
    ordered = sorted(values)
    position = share * (len(ordered) - 1)
    low = math.floor(position)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (position - low)


def expected_timing(pairs: list[tuple[int, int]]) -> dict[str, float]:
    """The summary of one method's (stamp, log time) pairs, written from the definitions."""
    pairs = sorted(pairs, key=lambda pair: pair[1])
    arrivals = [arrival for _, arrival in pairs]
    delays = [(arrival - stamp) / 1e6 for stamp, arrival in pairs]
    intervals = [b - a for a, b in itertools.pairwise(arrivals)]
    jitter = [abs(b - a) / 1e6 for a, b in itertools.pairwise(intervals)]
    span = arrivals[-1] - arrivals[0]
    complete = span // 1_000_000_000
    windows = [
        sum(1 for t in arrivals if arrivals[0] + k * 10**9 <= t < arrivals[0] + (k + 1) * 10**9)
        for k in range(complete)
    ]
    return {
        "frames": len(pairs),
        "missed": FRAMES - len(pairs),
        "latency_median": _percentile(delays, 0.5),
        "latency_p95": _percentile(delays, 0.95),
        "latency_max": max(delays),
        "latency_mean": sum(delays) / len(delays),
        "fps": (len(pairs) - 1) / (span / 1e9),
        "fps_min": min(windows) if windows else math.nan,
        "jitter_mean": sum(jitter) / len(jitter),
        "jitter_max": max(jitter),
    }


def test_the_summaries_equal_an_independent_computation(
    varied: tuple[Path, Path, dict[str, int]],
) -> None:
    bag, out, _ = varied
    document = json.loads((out / "summary.json").read_text())
    (sequence,) = document["sequences"]
    latency = sequence["latency"]
    exported = json.loads((out / TIMING_JSON).read_text())
    assert len(exported) == len(METHODS)
    bm_misses = any(sequence["counts"][m]["dropped"] for m in METHODS)
    assert bm_misses, "the varied bag leaves frames out for one method"
    for method, pairs in logged(bag).items():
        expected = expected_timing(pairs)
        stored = latency[method]
        for name, value in expected.items():
            assert stored[name] == pytest.approx(value, rel=1e-12, abs=1e-12), (method, name)
        assert stored["missed"] == sequence["counts"][method]["dropped"]
        arrivals = sorted(arrival for _, arrival in pairs)
        benchmark = exported[f"{sequence['sequence']}/{method}"]
        their_rate = len(pairs) / ((arrivals[-1] - arrivals[0]) / 1e9)  # n frames, n − 1 gaps
        assert benchmark["BasicPerformanceMetrics.MEAN_FRAME_RATE"] == pytest.approx(their_rate)
        assert benchmark["BasicPerformanceMetrics.NUM_FRAMES_SENT"] == FRAMES
        assert benchmark["BasicPerformanceMetrics.NUM_MISSED_FRAMES"] == expected["missed"]
        assert benchmark["BasicPerformanceMetrics.MAX_JITTER"] == pytest.approx(
            expected["jitter_max"]
        )
        assert benchmark["BasicPerformanceMetrics.MEAN_LATENCY"] == pytest.approx(
            expected["latency_mean"]
        )
    assert len({latency[m]["latency_p95"] for m in METHODS}) == len(METHODS)
    assert any(latency[m]["jitter_max"] > 0 for m in METHODS)


def _groups(out: Path, measures: list[str]) -> dict[str, int]:
    with ResultsStore.open(out) as store:
        summary = summarize(store, measures)
    models = summary.sequences[0].models
    assert models is not None
    return dict(models.groups)


def test_the_fastest_and_the_most_accurate_share_the_first_group(tmp_path: Path) -> None:
    _, args, orders = fast_rough_bag(tmp_path, FRAMES)
    assert orders["rough"] < orders["fine"]
    out = tmp_path / "res"
    assert main(args) == 0
    alone = _groups(out, ["sze", "bmpre"])
    assert alone == {"fine": 1, "rough": 2}  # over accuracy alone, rough is dominated
    assert _groups(out, ["sze", "bmpre", "latency_p95"]) == {"fine": 1, "rough": 1}


def test_latency_objectives_from_the_command_line(
    made: tuple[Path, Path, dict[str, int]], tmp_path: Path
) -> None:
    bag, out, orders = made
    measures = ["--objective-measures", "sze", "bmpre", "latency_p95"]
    export = tmp_path / "objectives.csv"
    assert main(["models", str(out), *measures, "--export", str(export)]) == 0
    with open(export, newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    column = rows[0].index("latency_p95 @drive")
    assert [name for name in rows[0] if name.startswith("latency")] == ["latency_p95 @drive"]
    assert {row[0]: float(row[column]) for row in rows[1:]} == {
        m: method_latency_ns(orders[m]) / 1e6 for m in METHODS
    }
    run_bag(bag, tmp_path / "res", *measures)
    document = json.loads((tmp_path / "res" / "summary.json").read_text())
    assert "latency_p95 @drive" in document["sequences"][0]["objectives"]


def drop_timing(folder: Path) -> None:
    """Make ``folder``'s database one written before arrival times were recorded."""
    connection = sqlite3.connect(folder / "results.sqlite")
    connection.execute(f"DROP TABLE {TIMING_TABLE}")
    connection.commit()
    connection.close()


def test_an_older_database_reads_as_no_latency_recorded(
    made: tuple[Path, Path, dict[str, int]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag, _, _ = made
    old = tmp_path / "old"
    run_bag(bag, old, "--slice", "0.5")
    drop_timing(old)
    with ResultsStore.open(old) as store:
        assert store.timing(store.sequences()[0]) is None
        summary = summarize(store)
    assert summary.sequences[0].timing is None
    assert summary.to_dict()["sequences"][0]["latency"] is None
    assert main(["models", str(old), "--objective-measures", "sze", "latency_p95"]) == 2
    assert "no latency recorded" in capsys.readouterr().err
    connection = sqlite3.connect(old / "results.sqlite")  # as killed after its first unit
    (first,) = connection.execute("SELECT MIN(stamp) FROM frames").fetchone()
    connection.execute("DELETE FROM units WHERE ordinal > 0")
    connection.execute("DELETE FROM frames WHERE stamp >= ?", (first + 450_000_000,))
    connection.commit()
    connection.close()
    assert main(bag_args(bag, old, "--slice", "0.5", "--resume")) == 0
    assert "latency: not recorded" in capsys.readouterr().out
    with ResultsStore.open(old) as store:
        assert not store.records_timing()
        assert len(store.stamps(store.sequences()[0])) == FRAMES  # the rest written again


def test_the_latency_table_fits_the_width_and_shows_every_method(
    varied: tuple[Path, Path, dict[str, int]],
) -> None:
    _, out, _ = varied
    with ResultsStore.open(out) as store:
        summary = summarize(store)
        timing = summary.sequences[0].timing
    assert timing is not None
    text = latency_text(timing)
    assert max(len(line) for line in text.splitlines()) <= WIDTH
    for method, row in timing.items():
        line = next(line for line in text.splitlines() if line.split()[:1] == [method])
        assert line.split()[1:3] == [str(row.frames), str(row.missed)]
    assert "latency: arrival" in run_summary_text(summary)


def test_merge_keeps_the_latency_only_when_every_input_recorded_it(
    made: tuple[Path, Path, dict[str, int]], tmp_path: Path
) -> None:
    _, out, _ = made
    bag, _ = make(tmp_path, "north")
    run_bag(bag, tmp_path / "north_res")
    assert main(["merge", str(tmp_path / "both"), str(out), str(tmp_path / "north_res")]) == 0
    with ResultsStore.open(tmp_path / "both") as store:
        merged = {s: store.timing(s) for s in store.sequences()}
    with ResultsStore.open(out) as store:
        assert merged["drive"] == store.timing("drive")
    exported = json.loads((tmp_path / "both" / TIMING_JSON).read_text())
    assert sorted(exported) == sorted(f"{s}/{m}" for s in ("drive", "north") for m in METHODS)
    drop_timing(tmp_path / "north_res")
    assert main(["merge", str(tmp_path / "part"), str(out), str(tmp_path / "north_res")]) == 0
    with ResultsStore.open(tmp_path / "part") as store:
        assert not store.records_timing()
    assert not (tmp_path / "part" / TIMING_JSON).exists()


def test_an_undefined_timing_objective_is_one_line_naming_it() -> None:
    """Two arrivals have no jitter (it needs three): refused, not ranked on NaN."""
    timing = {"a": timing_of([0, 100], [20, 130], 0), "b": timing_of([0, 100], [30, 140], 0)}
    names, block = timing_objectives(timing, "s", ["a", "b"], ["latency_max", "fps"])
    assert names == ["latency_max @s", "fps @s"]
    np.testing.assert_allclose(block, [[30e-6, -1e9 / 110], [40e-6, -1e9 / 110]], rtol=1e-12)
    with pytest.raises(ConfigurationError, match=r"jitter_max .* undefined for a over sequence s"):
        timing_objectives(timing, "s", ["a", "b"], ["jitter_max"])
    with pytest.raises(ConfigurationError, match="no latency recorded for sequence s"):
        timing_objectives(None, "s", ["a", "b"], ["latency_p95"])
