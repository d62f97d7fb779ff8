"""Tests of the results database (dispeval_ros.io.store).

Scores come from the real Evaluator on small synthetic maps. The crash tests run a writer in a
subprocess, kill it (SIGKILL on POSIX) and check that only whole units survive and that a
resumed run ends with exactly the database of an uninterrupted one.
"""

from __future__ import annotations

import csv
import math
import pickle
import random
import sqlite3
import subprocess
import sys
import tempfile
import textwrap
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from store_support import dump

from dispeval_ros import Camera, Evaluator, Scores
from dispeval_ros.cli.main import cli_advice
from dispeval_ros.core.measures import SUM_FIELDS, quantile_level
from dispeval_ros.errors import ConfigurationError, InputError, ResultsConflictError
from dispeval_ros.io.store import (
    RESULTS_FILE,
    TIMING_COLUMNS,
    FrameScores,
    MatchCounts,
    Problem,
    ResultsStore,
    failure_record,
)
from dispeval_ros.ros.params import ros_advice

CONFIG = {
    "criteria": ["all", "visibility", "depth"],
    "measures": None,
    "missing": "interpolate",
    "delta": 1.0,
    "mu": 0.01,
    "tolerance": 0.005,
    "topics": {"gt": "/gt/disparity", "methods": ["/sgbm", "/bm", "/ref"]},
}
METHODS = ("sgbm", "bm", "ref")
EVALUATOR = Evaluator(criteria=("all", "visibility", "depth"))
CAMERA = Camera(f=100.0, baseline=0.5)


# ------------------------------------------------------------------------------ helpers


def ground_truth(stamp: int) -> np.ndarray:
    """A small slanted plane with a step (no step, so no boundary, every 4th stamp)."""
    _, x = np.mgrid[0:24, 0:32]
    gt = 10.0 + 0.2 * x + (x >= 16) * (4.0 + stamp % 3) * (stamp % 4 != 3)
    gt[0, : 1 + stamp % 4] = np.nan
    return gt.astype(np.float32)


def estimate(gt: np.ndarray, stamp: int, method: int) -> np.ndarray:
    rng = np.random.default_rng(1000 * stamp + method)
    est = gt + rng.normal(0.0, 0.4 * (method + 1), gt.shape)
    est[rng.random(gt.shape) < 0.1] = np.nan  # missing estimates
    return est.astype(np.float32)


def frames_of(sequence: str, stamps: range, camera: Camera | None = None) -> list[FrameScores]:
    frames = []
    for stamp in stamps:
        gt = ground_truth(stamp)
        for index, method in enumerate(METHODS):
            scores = EVALUATOR.score(gt, estimate(gt, stamp, index), camera=camera)
            frames.append(FrameScores(sequence, stamp * 10_000_000, method, scores))
    return frames


def plan() -> list[tuple[str, str, list[FrameScores], list[Problem], dict[str, MatchCounts]]]:
    """Two sequences × 6 units × 4 stamps × 3 methods, with problems and match counts."""
    units = []
    for number, sequence in enumerate(("kitti_00", "drive_b")):
        camera = CAMERA if number == 0 else None
        for unit in range(6):
            stamps = range(unit * 4, unit * 4 + 4)
            frames = frames_of(sequence, stamps, camera)
            problems = [Problem(sequence, stamps[1] * 10_000_000, "bm", f"decode error {unit}")]
            if unit % 2:
                problems.append(Problem(sequence, None, None, "time jump"))
            counts = {m: MatchCounts(4, unit, unit % 2, 0) for m in METHODS}
            units.append((sequence, f"{unit:03d}", frames, problems, counts))
    return units


PLAN = plan()


def write_plan(store: ResultsStore, units=PLAN) -> None:
    for sequence, unit, frames, problems, counts in units:
        store.set_sequence(sequence, f"/bags/{sequence}.mcap", {"camera": "/cam", "start": 0})
        store.add_unit(sequence, unit, frames, problems, counts)


def same(a: float, b: float) -> bool:
    """Exact float equality, NaN equal to NaN."""
    return (math.isnan(a) and math.isnan(b)) or a == b


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The database of an uninterrupted run of PLAN."""
    directory = tmp_path_factory.mktemp("reference")
    with ResultsStore.create(directory, CONFIG) as store:
        write_plan(store)
    return directory


# ------------------------------------------------------------------------------ round trips


def test_every_value_round_trips_exactly(reference: Path) -> None:
    nan_seen = 0
    with ResultsStore.open(reference) as store:
        assert store.measures() == list(EVALUATOR.measures)
        for sequence, _, frames, _, _ in PLAN:
            for frame in frames:
                stored = store.frame_scores(sequence, frame.stamp)[frame.method]
                original = frame.scores
                assert stored.criteria == original.criteria
                assert stored.sums.tobytes() == np.asarray(original.sums, np.float64).tobytes()
                assert np.array_equal(stored.thresholds, original.thresholds)
                assert stored.relative == original.relative
                assert stored.policy == original.policy
                for criterion in original.criteria:
                    for name, value in original[criterion].items():
                        assert same(stored[criterion][name], value), (criterion, name)
                        nan_seen += math.isnan(value)
            rows = list(store.frame_rows(sequence))
            by_key = {(r["stamp"], r["method"], r["criterion"]): r for r in rows}
            assert len(by_key) == len(rows)
            for frame in frames:
                for criterion in frame.scores.criteria:
                    row = by_key[frame.stamp, frame.method, criterion]
                    assert row["n"] == frame.scores[criterion]["n"]
                    for name in EVALUATOR.measures:
                        assert same(row[name], frame.scores[criterion][name])  # type: ignore[arg-type]
    assert nan_seen > 0  # measures of the empty 'boundary' criterion
    db = sqlite3.connect(reference / RESULTS_FILE)
    nulls = db.execute('SELECT COUNT(*) FROM frames WHERE "mae" IS NULL').fetchone()[0]
    db.close()
    assert nulls > 0  # NaN is stored as NULL


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # 100 × 1e308
@settings(max_examples=25, deadline=None)
@given(
    sums=hnp.arrays(
        np.float64,
        (3, len(SUM_FIELDS)),
        elements=st.floats(min_value=0.0, allow_infinity=True, allow_subnormal=True)
        | st.just(math.nan),
    ),
    stamp=st.integers(min_value=-(2**63), max_value=2**63 - 1),
)
def test_any_accumulator_row_round_trips_bit_for_bit(sums: np.ndarray, stamp: int) -> None:
    template = frames_of("s", range(1))[0].scores
    scores = Scores(
        criteria=("all", "near", "bad \"name'"),
        measures=template.measures,
        sums=sums,
        thresholds=template.thresholds,
        relative=True,
    )
    with tempfile.TemporaryDirectory() as folder:
        with ResultsStore.create(Path(folder), {}) as store:
            store.add_unit("s", "u", [FrameScores("s", stamp, "m", scores)])
        with ResultsStore.open(Path(folder)) as store:
            stored = store.frame_scores("s", stamp)["m"]
            rows = list(store.frame_rows())
    assert stored.sums.tobytes() == sums.tobytes()
    for row, criterion in zip(rows, scores.criteria, strict=True):
        assert row["stamp"] == stamp
        for name in scores.measures:
            assert same(row[name], scores[criterion][name])  # type: ignore[arg-type]


def test_csv_export_reads_back_identical_numbers(reference: Path, tmp_path: Path) -> None:
    target = tmp_path / "frames.csv"
    with ResultsStore.open(reference) as store:
        written = store.export_csv(target)
        rows = list(store.frame_rows())
        measures = store.measures()
    with open(target, newline="", encoding="utf-8") as handle:
        table = list(csv.reader(handle))
    assert table[0] == ["sequence", "stamp", "method", "criterion", "n", *measures, *TIMING_COLUMNS]
    assert written == len(rows) == len(table) - 1 == 2 * 6 * 4 * 3 * 7
    empty = 0
    for line, row in zip(table[1:], rows, strict=True):
        assert line[:4] == [row["sequence"], str(row["stamp"]), row["method"], row["criterion"]]
        for cell, name in zip(line[4 : -len(TIMING_COLUMNS)], ["n", *measures], strict=True):
            value = math.nan if cell == "" else float(cell)
            empty += cell == ""
            assert same(value, float(row[name])), (name, cell)  # type: ignore[arg-type]
    assert empty > 0


# ------------------------------------------------------------------------------ sequence sums


def test_sequence_scores_are_sums_of_sums(reference: Path) -> None:
    with ResultsStore.open(reference) as store:
        for sequence in ("kitti_00", "drive_b"):
            frames = [f for s, _, fs, _, _ in PLAN if s == sequence for f in fs]
            totals = store.sequence_scores(sequence)
            assert list(totals) == list(METHODS)
            for method in METHODS:
                parts = sorted((f for f in frames if f.method == method), key=lambda f: f.stamp)
                expected = Scores.combine([f.scores for f in parts])
                got = totals[method]
                assert got.criteria == expected.criteria
                assert got.sums.tobytes() == expected.sums.tobytes()
                for criterion in expected.criteria:
                    for name, value in expected[criterion].items():
                        if quantile_level(name) is None:
                            assert same(got[criterion][name], value), (criterion, name)
                        else:
                            assert math.isnan(got[criterion][name])  # not summable
            # a subset of stamps and all sequences together
            stamps = store.stamps(sequence)[::3]
            subset = store.sequence_scores(sequence, stamps)["bm"]
            chosen = [f.scores for f in frames if f.method == "bm" and f.stamp in stamps]
            assert subset.sums.tobytes() == Scores.combine(chosen).sums.tobytes()
        with pytest.raises(ConfigurationError, match=r"metric SZE .* relative SZE"):
            store.sequence_scores()  # kitti_00 has a camera, drive_b none: as Scores.combine


def test_scores_over_all_sequences(tmp_path: Path) -> None:
    units = [("a", frames_of("a", range(3))), ("b", frames_of("b", range(5, 7)))]
    with ResultsStore.create(tmp_path, CONFIG) as store:
        for sequence, frames in units:
            store.add_unit(sequence, "0", frames)
        everything = store.sequence_scores()
        some = store.sequence_scores(stamps=[0, 60_000_000])["sgbm"]
    for method in METHODS:
        parts = [f.scores for _, frames in units for f in frames if f.method == method]
        assert everything[method].sums.tobytes() == Scores.combine(parts).sums.tobytes()
    chosen = [units[0][1][0].scores, units[1][1][3].scores]
    assert some.sums.tobytes() == Scores.combine(chosen).sums.tobytes()


def test_sequence_mean_is_not_the_mean_of_frame_means(tmp_path: Path) -> None:
    gt = np.full((8, 8), 20.0, np.float32)
    small = gt.copy()
    small[2:, :] = np.nan  # frame 1: 16 valid points, error 4 each
    frames = [
        FrameScores("s", 1, "m", EVALUATOR.score(small, small + 4.0)),
        FrameScores("s", 2, "m", EVALUATOR.score(gt, gt + 0.5)),  # 64 points, error 0.5
    ]
    with ResultsStore.create(tmp_path, CONFIG) as store:
        store.add_unit("s", "0", frames)
        mae = store.sequence_scores("s")["m"]["all"]["mae"]
        per_frame = [store.frame_scores("s", stamp)["m"]["all"]["mae"] for stamp in (1, 2)]
    assert mae == pytest.approx((16 * 4.0 + 64 * 0.5) / 80)
    assert mae != pytest.approx(sum(per_frame) / 2)


# ------------------------------------------------------------------------------ writing rules


def test_add_unit_is_idempotent_and_counts_add_up(tmp_path: Path, reference: Path) -> None:
    with ResultsStore.create(tmp_path, CONFIG) as store:
        write_plan(store)
        assert store.is_done("kitti_00", "003")
        assert store.done_units("drive_b") == {f"{u:03d}" for u in range(6)}
        sequence, unit, frames, problems, counts = PLAN[0]
        store.add_unit(sequence, unit, frames[:1], problems * 2, counts)  # already done: no-op
        assert store.match_counts("drive_b") == {m: MatchCounts(24, 15, 3, 0) for m in METHODS}
        assert store.problems("drive_b")[:3] == [
            Problem("drive_b", 10_000_000, "bm", "decode error 0"),
            Problem("drive_b", 50_000_000, "bm", "decode error 1"),
            Problem("drive_b", None, None, "time jump"),
        ]
        assert len(store.problems()) == 2 * 9
    assert dump(tmp_path) == dump(reference)


def test_first_seen_orders_and_metadata(tmp_path: Path) -> None:
    frames = frames_of("b", range(2))
    reordered = [FrameScores("b", f.stamp, {"sgbm": "z", "bm": "y", "ref": "a"}[f.method], f.scores)
                 for f in frames]  # fmt: skip
    with ResultsStore.create(tmp_path, CONFIG) as store:
        store.set_sequence("b", "/bags/b.mcap", {"start": 1, "end": 2})
        store.add_unit("b", "1", reordered[3:])
        store.add_unit("a", "1", [FrameScores("a", 5, "a", frames[0].scores)])
        store.add_unit("b", "0", reordered[:3])
        store.set_sequence("b", "/bags/b2.mcap", {"end": 3})  # upsert keeps the order
        assert store.sequences() == ["b", "a"]
        assert store.methods() == ["z", "y", "a"]
        assert store.criteria() == list(frames[0].scores.criteria)
        assert store.sequence_info("b") == ("/bags/b2.mcap", {"end": 3})
        assert store.sequence_info("a") == ("", {})
        rows = [(r["stamp"], r["method"], r["criterion"]) for r in store.frame_rows("b")]
        assert rows == [(f.stamp, f.method, c) for f in reordered for c in f.scores.criteria]
        assert [r["criterion"] for r in store.frame_rows("b", "a")][:2] == ["all", "occluded"]
        assert store.stamps("b") == [0, 10_000_000]
        assert store.config() == CONFIG


def test_common_stamps_need_every_method(tmp_path: Path) -> None:
    frames = frames_of("s", range(3))
    kept = [f for f in frames if not (f.stamp == 10_000_000 and f.method == "bm")]
    with ResultsStore.create(tmp_path, CONFIG) as store:
        store.add_unit("s", "0", kept)
        assert store.stamps("s") == [0, 10_000_000, 20_000_000]
        assert store.common_stamps("s") == [0, 20_000_000]
        assert set(store.frame_scores("s", 10_000_000)) == {"sgbm", "ref"}


def test_a_unit_without_frames_keeps_its_problems_and_counts(tmp_path: Path) -> None:
    with ResultsStore.create(tmp_path, CONFIG) as store:
        problem = Problem("s", 5, "bm", "size mismatch: 24×32 vs 12×16")
        store.add_unit("s", "0", [], [problem], {"bm": MatchCounts(0, 1, 0, 1)})
        assert store.is_done("s", "0")
        assert store.measures() == []
        assert list(store.frame_rows()) == []
        assert store.sequence_scores("s") == {}
        assert store.frame_scores("s", 5) == {}
        assert store.stamps("s") == store.common_stamps("s") == []
        store.add_unit("s", "1", frames_of("s", range(1)))
    with ResultsStore.open(tmp_path) as store:
        assert store.problems() == [problem]
        assert store.match_counts("s") == {"bm": MatchCounts(0, 1, 0, 1)}
        assert store.methods() == list(METHODS)
        assert store.measures() == list(EVALUATOR.measures)


def test_a_failing_unit_leaves_nothing(tmp_path: Path) -> None:
    frames = frames_of("s", range(2))
    with ResultsStore.create(tmp_path, CONFIG) as store:
        store.add_unit("s", "0", frames[:3])
        before = dump(tmp_path)
        with pytest.raises(ValueError, match="another unit"):
            store.add_unit(
                "s", "1", frames[3:] + frames[:1], counts={"bm": MatchCounts(1, 0, 0, 0)}
            )
        assert dump(tmp_path) == before
        assert not store.is_done("s", "1")
        other = Evaluator(measures=("mae", "bad_3"))
        gt = ground_truth(0)
        odd = [FrameScores("s", 99, "bm", other.score(gt, gt))]
        with pytest.raises(ConfigurationError, match="measures"):
            store.add_unit("s", "2", odd)
        assert dump(tmp_path) == before


def test_a_failure_record_keeps_its_unit_undone_and_is_replaced(tmp_path: Path) -> None:
    """A unit that failed every attempt is recorded under failure_record(unit): its problem
    is kept, the unit stays undone (a resume retries it); a newer failure replaces the
    record, the unit written drops it, and a record of a done unit is a no-op."""
    frames = frames_of("s", range(2))

    def failure(message: str) -> None:
        store.add_unit("s", failure_record("1"), [], [Problem("s", None, None, message)])

    with ResultsStore.create(tmp_path, CONFIG) as store:
        store.add_unit("s", "0", frames[:3])
        failure("unit 1 failed 3 times: first")
        assert store.done_units("s") == {"0"}
        assert store.failed_units("s") == {"1"}
        failure("unit 1 failed 3 times: second")
        assert [p.message for p in store.problems()] == ["unit 1 failed 3 times: second"]
        store.add_unit("s", "1", frames[3:])
        assert store.done_units("s") == {"0", "1"}
        assert store.failed_units("s") == set()
        assert store.problems() == []
        failure("a late record of a unit written meanwhile")
        assert store.failed_units("s") == set()
        assert store.problems() == []


# ------------------------------------------------------------------------------ create / open


def test_existing_results_need_resume(reference: Path) -> None:
    with pytest.raises(ResultsConflictError) as caught:
        ResultsStore.create(reference, CONFIG)
    conflict = caught.value
    assert str(conflict) == f"{reference} already holds results"  # the fact, no front end's words
    assert conflict.resumable
    cli = str(cli_advice(conflict))
    assert cli == (
        f"{reference} already holds results; use --resume to continue them or choose another --out"
    )
    ros = str(ros_advice(conflict))
    assert ros == (
        f"{reference} already holds results; set resume:=true to continue them or set another "
        "output_dir"
    )
    assert "--" not in ros
    assert ":=" not in cli


def test_resume_with_another_configuration_names_the_key(tmp_path: Path) -> None:
    with ResultsStore.create(tmp_path, CONFIG) as store:
        write_plan(store, PLAN[:1])
    changed = {**CONFIG, "delta": 2.0}
    with pytest.raises(ResultsConflictError, match=r"'delta' is 1\.0 there but 2\.0 now") as caught:
        ResultsStore.create(tmp_path, changed, resume=True)
    assert "\n" not in str(caught.value)
    assert not caught.value.resumable
    assert str(ros_advice(caught.value)).endswith(
        "now; resume with the same parameters or set another output_dir"
    )
    with pytest.raises(ConfigurationError, match="'extra' is \\(absent\\) there but 1 now"):
        ResultsStore.create(tmp_path, {**CONFIG, "extra": 1}, resume=True)
    same_values = {"topics": CONFIG["topics"], **CONFIG}  # key order does not matter
    with ResultsStore.create(tmp_path, same_values, resume=True) as store:
        assert store.done_units("kitti_00") == {"000"}


def test_resume_continues_to_the_uninterrupted_result(tmp_path: Path, reference: Path) -> None:
    with ResultsStore.create(tmp_path, CONFIG) as store:
        write_plan(store, PLAN[:5])
    with ResultsStore.create(tmp_path, dict(CONFIG), resume=True) as store:
        write_plan(store)  # the first five are skipped
    assert dump(tmp_path) == dump(reference)


def test_open_refuses_what_is_not_results(tmp_path: Path, reference: Path) -> None:
    text = tmp_path / "notes.sqlite"
    text.write_text("not a database at all, just some text that is long enough\n" * 20)
    with pytest.raises(InputError, match=r"notes\.sqlite is not a results database") as caught:
        ResultsStore.open(text)
    assert "\n" not in str(caught.value)
    with pytest.raises(InputError, match="no such file"):
        ResultsStore.open(tmp_path / "missing")
    with pytest.raises(InputError, match=RESULTS_FILE):
        ResultsStore.open(tmp_path)  # a folder without results
    foreign = tmp_path / "foreign.sqlite"
    sqlite3.connect(foreign).execute("CREATE TABLE t (x)").connection.close()
    with pytest.raises(InputError, match="not dispeval results"):
        ResultsStore.open(foreign)
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / RESULTS_FILE).write_bytes(text.read_bytes())
    with pytest.raises(InputError, match="not a results database"):
        ResultsStore.create(folder, CONFIG, resume=True)
    with ResultsStore.open(reference / RESULTS_FILE) as store:
        assert store.sequences() == ["kitti_00", "drive_b"]
        with pytest.raises(ValueError, match="read-only"):
            store.add_unit("x", "0", [])


# ------------------------------------------------------------------------------ crashes

WRITER = textwrap.dedent(
    """
    import os, pickle, signal, sys
    from pathlib import Path
    from dispeval_ros.io.store import ResultsStore

    out, plan_file, die_at, die_in = sys.argv[1:5]
    config, units = pickle.loads(Path(plan_file).read_bytes())
    store = ResultsStore.create(Path(out), config, resume=True)

    class Dying:
        # the process dies right after statement `die_at` of unit number `die_in` ran
        def __init__(self, db):
            self.db, self.seen = db, 0
        def __getattr__(self, name):
            return getattr(self.db, name)
        def _ran(self, sql):
            if sql.startswith(die_at):
                self.seen += 1
                if self.seen > int(die_in):
                    os.kill(os.getpid(), getattr(signal, "SIGKILL", signal.SIGTERM))
        def execute(self, sql, *parameters):
            result = self.db.execute(sql, *parameters)
            self._ran(sql)
            return result
        def executemany(self, sql, rows):
            result = self.db.executemany(sql, rows)
            self._ran(sql)
            return result

    if die_at:
        store._db = Dying(store._db)
    for sequence, unit, frames, problems, counts in units:
        store.set_sequence(sequence, f"/bags/{sequence}.mcap", {"camera": "/cam", "start": 0})
        store.add_unit(sequence, unit, frames, problems, counts)
        print(unit, flush=True)
    print("finished", flush=True)
    """
)


def big_plan() -> list[tuple[str, str, list[FrameScores], list[Problem], dict[str, MatchCounts]]]:
    """300 units of 5 stamps × 3 methods (real scores reused), long enough to be killed."""
    pool = [f.scores for _, _, frames, _, _ in PLAN for f in frames]
    units = []
    for unit in range(300):
        stamps = range(unit * 5, unit * 5 + 5)
        frames = [
            FrameScores("long", stamp, method, pool[(3 * stamp + index) % len(pool)])
            for stamp in stamps
            for index, method in enumerate(METHODS)
        ]
        problems = [Problem("long", stamps[0], "sgbm", "late")] if unit % 7 == 0 else []
        units.append(("long", f"{unit:04d}", frames, problems, {"bm": MatchCounts(5, 1, 0, 0)}))
    return units


def uncached(units: list) -> list:
    """The units with fresh Scores, so that the writer derives every measure itself (slower)."""
    fresh: dict[int, Scores] = {}
    for scores in (f.scores for _, _, frames, _, _ in units for f in frames):
        fresh.setdefault(
            id(scores),
            Scores(
                criteria=scores.criteria,
                measures=scores.measures,
                sums=scores.sums,
                thresholds=scores.thresholds,
                quantiles=scores.quantiles,
                relative=scores.relative,
                overlapping=scores.overlapping,
                policy=scores.policy,
            ),
        )
    return [
        (sequence, unit, [replace(f, scores=fresh[id(f.scores)]) for f in frames], problems, counts)
        for sequence, unit, frames, problems, counts in units
    ]


def run_writer(
    folder: Path, units: list, die_at: str = "", die_in: int = 0
) -> subprocess.Popen[str]:
    """Start the writer script on ``units`` (resuming the results in ``folder``)."""
    script, plan_file = folder.parent / f"{folder.name}.py", folder.parent / f"{folder.name}.pickle"
    script.write_text(WRITER)
    plan_file.write_bytes(pickle.dumps((CONFIG, uncached(units))))
    command = [sys.executable, str(script), str(folder), str(plan_file), die_at, str(die_in)]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def check_whole_units(directory: Path, units: list) -> set[tuple[str, str]]:
    """Only done units have rows, and each done unit has all of its rows; the done units."""
    database = dump(directory)
    done = {(s, u) for s, u, _ in database["units"]}  # type: ignore[attr-defined]
    expected: set[tuple[object, ...]] = set()
    problems: set[tuple[object, ...]] = set()
    for sequence, unit, frames, unit_problems, _ in units:
        if (sequence, unit) in done:
            expected |= {
                (sequence, f.stamp, f.method, c) for f in frames for c in f.scores.criteria
            }
            problems |= {(sequence, unit, i) for i in range(len(unit_problems))}
    stored = {row[:4] for row in database.get("frames", [])}  # type: ignore[attr-defined]
    assert stored == expected
    assert {row[:3] for row in database["problems"]} == problems  # type: ignore[attr-defined]
    for sequence, method, _, *counts in database["match_counts"]:  # type: ignore[attr-defined]
        added = [p[4][method] for p in units if p[0] == sequence and (sequence, p[1]) in done]
        assert counts == [
            sum(c.matched for c in added),
            sum(c.unmatched for c in added),
            sum(c.dropped for c in added),
            sum(c.failed for c in added),
        ]
    return done


@pytest.mark.parametrize("die_at", ["INSERT INTO frames", "INSERT INTO units"])
def test_kill_inside_a_unit_loses_only_that_unit(
    tmp_path: Path, reference: Path, die_at: str
) -> None:
    folder = tmp_path / "out"
    ResultsStore.create(folder, CONFIG).close()
    # dies inside unit 3: after its frame rows, or after all of it but before the commit
    process = run_writer(folder, PLAN, die_at, die_in=3)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode != 0, stderr
    assert stdout.split() == ["000", "001", "002"]
    assert check_whole_units(folder, PLAN) == {("kitti_00", f"{u:03d}") for u in range(3)}
    with ResultsStore.open(folder) as store:
        assert not store.is_done("kitti_00", "003")
        assert store.stamps("kitti_00") == [s * 10_000_000 for s in range(12)]
    with ResultsStore.create(folder, CONFIG, resume=True) as store:
        write_plan(store)
    assert dump(folder) == dump(reference)


def test_random_kills_then_resume_match_an_uninterrupted_run(tmp_path: Path) -> None:
    units = big_plan()
    whole = tmp_path / "whole"
    with ResultsStore.create(whole, CONFIG) as store:
        write_plan(store, units)
    folder = tmp_path / "killed"
    ResultsStore.create(folder, CONFIG).close()
    chance = random.Random()
    delays, interrupted = [], 0
    for _ in range(3):
        process = run_writer(folder, units)
        assert process.stdout is not None
        process.stdout.readline()  # one unit committed: the writer is under way
        delays.append(round(chance.uniform(0.0, 0.2), 3))  # the writer needs ≥ 0.4 s
        time.sleep(delays[-1])
        process.kill()
        stdout, _ = process.communicate(timeout=30)
        interrupted += "finished" not in stdout
        check_whole_units(folder, units)
    assert interrupted, f"the writer always finished before the kill (delays {delays})"
    with ResultsStore.create(folder, CONFIG, resume=True) as store:
        write_plan(store, units)
    assert dump(folder) == dump(whole), f"kill delays {delays}"
