"""``dispeval bag`` on every executor (in process, process pool, Dask), faults, and merge."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from bag_support import METHODS, bag_args, database_content

from dispeval_ros.cli.main import main
from dispeval_ros.errors import InputError
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline import executors as executors_module
from dispeval_ros.offline import units as units_module
from dispeval_ros.offline.bag_eval import RunReport, evaluate_bags
from dispeval_ros.offline.dask_executor import DaskExecutor, check_worker
from dispeval_ros.offline.make_bag import (
    bag_config,
    synthetic_frames,
    write_bag,
)
from dispeval_ros.offline.units import Unit, UnitRows, evaluate_unit, read_ahead
from dispeval_ros.stream.core import CoreConfig

SLICE = ("--slice", "0.2")


@pytest.fixture(scope="module")
def drives(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Two short drives (12 and 8 frames at 10 Hz, 192×64): 6 and 4 units of 0.2 s."""
    root = tmp_path_factory.mktemp("drives")
    paths = [root / "north", root / "south"]
    for path, frames, seed in zip(paths, (12, 8), (3, 4), strict=True):
        write_bag(
            path, synthetic_frames(frames, 192, 64, 10.0, seed=seed), storage="rosbag2-sqlite3"
        )
    return paths


def config() -> CoreConfig:
    return bag_config(METHODS)


def bag_command(bags: list[Path], out: Path, *extra: str) -> list[str]:
    """``dispeval bag`` of several bags, as test_bag_pipeline runs one."""
    command = bag_args(bags[0], out, *SLICE, *extra)
    command[2:2] = map(str, bags[1:])
    return command


@pytest.fixture(scope="module")
def reference(drives: list[Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Both drives with --jobs 1: the database every other way must reproduce."""
    out = tmp_path_factory.mktemp("reference")
    assert main(bag_command(drives, out)) == 0
    return out


def units_stored(out: Path) -> int:
    database = out / "results.sqlite"
    if not database.exists():
        return 0
    try:
        with sqlite3.connect(database, timeout=5) as connection:
            return int(connection.execute("SELECT COUNT(*) FROM units").fetchone()[0])
    except sqlite3.Error:
        return 0


def test_local_cluster_gives_the_database_of_one_process(
    drives: list[Path], reference: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(bag_command(drives, tmp_path, "--scheduler", "local:2")) == 0
    capsys.readouterr()
    assert database_content(tmp_path) == database_content(reference)


def test_killed_dask_worker_still_gives_the_same_database(
    drives: list[Path], reference: Path, tmp_path: Path
) -> None:
    executor = DaskExecutor(config(), "local:2")
    killed: list[int] = []

    def kill_a_worker(done: int, total: int, report: RunReport) -> None:
        if not killed:
            pids = executor.client.run(os.getpid)
            killed.append(next(iter(pids.values())))
            os.kill(killed[0], signal.SIGKILL)

    try:
        with ResultsStore.create(tmp_path, {**config().as_record(), "slice_ns": 200_000_000}) as s:
            evaluate_bags(
                drives, config(), s, executor=executor, slice_ns=200_000_000, progress=kill_a_worker
            )
    finally:
        executor.close()
    assert killed
    assert tables_but_run(tmp_path) == tables_but_run(reference)


def tables_but_run(folder: Path) -> dict[str, list[tuple]]:
    """Every table's rows (canonical order) but the configuration and provenance records.

    Both are written by hand here (the CLI writes them for a real run).
    """
    with sqlite3.connect(folder / "results.sqlite") as connection:
        names = [
            name
            for (name,) in connection.execute("SELECT name FROM sqlite_master WHERE type='table'")
            if name not in ("run", "provenance")
        ]
        return {
            name: sorted(connection.execute(f'SELECT * FROM "{name}"').fetchall(), key=repr)
            for name in names
        }


def test_killed_driver_resumes_to_the_same_database(
    drives: list[Path], reference: Path, tmp_path: Path
) -> None:
    out = tmp_path / "killed"
    command = [sys.executable, "-m", "dispeval_ros", *bag_command(drives, out)]
    process = subprocess.Popen(
        [*command, "--scheduler", "local:2"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # the driver and its local cluster, killed at once below
    )
    deadline = time.monotonic() + 50
    while units_stored(out) < 3 and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    stored = units_stored(out)
    assert 0 < stored < 20, "the run was not killed mid-way"
    resumed = subprocess.run(
        [*command, "--resume", "--jobs", "2"], capture_output=True, text=True, check=False
    )
    assert resumed.returncode == 0, resumed.stderr
    assert database_content(out) == database_content(reference)


def test_merge_of_two_halves_equals_the_whole_run(
    drives: list[Path], reference: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for index, drive in enumerate(drives):
        assert main(bag_command([drive], tmp_path / f"half{index}")) == 0
    capsys.readouterr()
    assert (
        main(["merge", str(tmp_path / "whole"), str(tmp_path / "half0"), str(tmp_path / "half1")])
        == 0
    )
    assert "2 sequences" in capsys.readouterr().out
    assert database_content(tmp_path / "whole") == database_content(reference)
    with ResultsStore.open(tmp_path / "whole") as store:  # how each half was made, kept
        merged = store.provenance()["inputs"]["merged"]
    assert [Path(item["results"]).parent.name for item in merged] == ["half0", "half1"]
    assert all(item["provenance"]["inputs"]["streams"] for item in merged)
    # merging a half again would count its units twice; another configuration is refused
    assert (
        main(["merge", str(tmp_path / "twice"), str(tmp_path / "half0"), str(tmp_path / "whole")])
        == 2
    )
    assert "twice" in capsys.readouterr().err
    assert main(bag_command([drives[0]], tmp_path / "other", "--tolerance", "5")) == 0
    capsys.readouterr()
    assert (
        main(["merge", str(tmp_path / "mixed"), str(tmp_path / "half1"), str(tmp_path / "other")])
        == 2
    )
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "tolerance_ns" in err


def failing_on(name: str, action: Callable[[], None]) -> Callable[[CoreConfig, Unit, int], object]:
    def evaluate(config: CoreConfig, unit: Unit, threads: int = 1) -> object:
        if unit.sequence == "north" and unit.name == name:
            action()
        return evaluate_unit(config, unit, threads)

    return evaluate


def test_a_unit_that_always_raises_is_a_problem_of_that_unit(
    drives: list[Path],
    reference: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    def boom() -> None:
        raise RuntimeError("out of cheese")

    monkeypatch.setattr(units_module, "evaluate_unit", failing_on("000003", boom))
    assert main(bag_command(drives, tmp_path)) == 0
    assert "2 unit(s) retried" in capsys.readouterr().out
    with ResultsStore.open(tmp_path) as store:
        (problem,) = store.problems()
        assert problem.sequence == "north"
        assert "unit 000003 failed 3 times" in problem.message
        assert "out of cheese" in problem.message
        assert "000003" not in store.done_units("north")  # so --resume tries it again
        assert store.failed_units("north") == {"000003"}
    # a resume that fails again replaces the failure record (one problem, the newest)
    assert main(bag_command(drives, tmp_path, "--resume")) == 0
    assert "1 unit(s) that had failed before tried again" in capsys.readouterr().out
    with ResultsStore.open(tmp_path) as store:
        assert len(store.problems()) == 1
    # the cause gone, --resume evaluates the unit and drops its failure record
    monkeypatch.setattr(units_module, "evaluate_unit", evaluate_unit)
    assert main(bag_command(drives, tmp_path, "--resume")) == 0
    assert "1 unit(s) that had failed before tried again" in capsys.readouterr().out
    with ResultsStore.open(tmp_path) as store, ResultsStore.open(reference) as expected:
        assert store.problems() == []
        assert store.failed_units("north") == set()
        for sequence in expected.sequences():
            assert store.done_units(sequence) == expected.done_units(sequence)
            assert store.stamps(sequence) == expected.stamps(sequence)
            for stamp in expected.stamps(sequence):
                ours, theirs = (s.frame_scores(sequence, stamp) for s in (store, expected))
                assert ours.keys() == theirs.keys()
                for method, scores in theirs.items():
                    np.testing.assert_array_equal(ours[method].sums, scores.sums)
            assert store.match_counts(sequence) == expected.match_counts(sequence)


DIE_ONCE = """
import os, sys
from pathlib import Path
from dispeval_ros.cli.main import main
from dispeval_ros.errors import InputError
from dispeval_ros.offline import units
evaluate, marker = units.evaluate_unit, Path(sys.argv[1])
def dies_once(config, unit, threads=1):
    if unit.sequence == "north" and unit.name == "000002" and not marker.exists():
        marker.touch()
        os._exit(1)
    return evaluate(config, unit, threads)
units.evaluate_unit = dies_once
sys.exit(main(sys.argv[2:]))
"""


def test_a_pool_worker_that_dies_is_retried_and_bystanders_are_kept(
    drives: list[Path], reference: Path, tmp_path: Path
) -> None:
    # in a fresh process (no threads yet): the pool forks, its workers see the patched unit
    marker = tmp_path / "died-once"
    command = bag_command(drives, tmp_path / "out", "--jobs", "2")
    run = subprocess.run(
        [sys.executable, "-c", DIE_ONCE, str(marker), *command],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    assert marker.exists()
    assert "retried" in run.stdout
    assert database_content(tmp_path / "out") == database_content(reference)


def test_unreachable_scheduler_is_one_line(
    drives: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(bag_command(drives, tmp_path, "--scheduler", "tcp://127.0.0.1:9")) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "tcp://127.0.0.1:9" in err
    assert main(bag_command(drives, tmp_path / "b", "--scheduler", "local:0")) == 2
    assert "local:N" in capsys.readouterr().err


def test_worker_check_names_the_path_and_the_version(drives: list[Path], tmp_path: Path) -> None:
    from dispeval_ros import __version__

    assert check_worker([str(drive) for drive in drives], __version__) is None
    missing = str(tmp_path / "elsewhere")
    assert missing in (check_worker([missing], __version__) or "")
    assert "0.0.0-other" in (check_worker([], "0.0.0-other") or "")


def test_scheduler_that_goes_away_is_one_error_and_the_run_resumes(
    drives: list[Path], reference: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import distributed

    cluster = distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, dashboard_address=None, silence_logs=50
    )
    executor = DaskExecutor(config(), cluster.scheduler_address)
    record = {**config().as_record(), "slice_ns": 200_000_000}

    def stop_the_scheduler(done: int, total: int, report: RunReport) -> None:
        if done == 2:
            cluster.close()

    try:
        with ResultsStore.create(tmp_path, record) as store:
            with pytest.raises(InputError, match=r"lost the Dask scheduler .* --resume"):
                evaluate_bags(
                    drives,
                    config(),
                    store,
                    executor=executor,
                    slice_ns=200_000_000,
                    progress=stop_the_scheduler,
                )
            assert 2 <= len(store.done_units("north")) < 10
    finally:
        executor.close()
        cluster.close()
    with ResultsStore.create(tmp_path, record, resume=True) as store:
        evaluate_bags(drives, config(), store, slice_ns=200_000_000)
    assert tables_but_run(tmp_path) == tables_but_run(reference)


def test_each_bag_is_opened_once_per_process(
    drives: list[Path], reference: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    opened: list[Path] = []
    original = units_module.BagSource

    def counting(path: Path) -> object:
        opened.append(Path(path))
        return original(path)

    monkeypatch.setattr(units_module, "BagSource", counting)
    record = {**config().as_record(), "slice_ns": 200_000_000}
    with ResultsStore.create(tmp_path, record) as store:
        report = evaluate_bags(drives, config(), store, slice_ns=200_000_000)
    assert report.units_done == 10  # several units per bag, each opening it anew if it could
    assert sorted(opened) == sorted(drives)
    assert tables_but_run(tmp_path) == tables_but_run(reference)


def bags_open_here() -> list[str]:
    """The bags a pool worker holds open (run in the worker)."""
    return sorted(key[0] for key in units_module._open_bags)


def test_pool_workers_open_the_first_bag_before_any_unit(drives: list[Path]) -> None:
    """``start`` forks the workers and each opens the first bag while the driver plans."""
    executor = executors_module.PoolExecutor(config(), 2)
    try:
        executor.start(drives)
        pool = executor._ensure_pool()
        held = [pool.submit(bags_open_here).result(timeout=60) for _ in range(4)]
        pids = {pool.submit(os.getpid).result(timeout=60) for _ in range(8)}
    finally:
        executor.close()
    assert held == [[str(drives[0])]] * 4
    assert len(pids) <= 2


def test_a_first_bag_that_cannot_open_leaves_the_workers_to_report_it(
    drives: list[Path], tmp_path: Path
) -> None:
    """A worker that cannot open the first bag starts anyway; the bag's units say why."""
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(b"not a bag")
    executor = executors_module.PoolExecutor(config(), 2)
    try:
        executor.start([broken, *drives])
        executor.submit(0, Unit(broken, "broken", "000000", 0, 10**9, 0))
        [(index, outcome)] = executor.completed()
    finally:
        executor.close()
    assert index == 0
    assert isinstance(outcome, UnitRows)
    assert outcome.problems == 1
    assert any(f"{broken}: cannot read bag" in str(row) for row in outcome.rows.problem_rows)


def test_auto_slices_follow_length_and_workers_and_resume_keeps_them(
    drives: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert units_module.auto_slice_ns(0, 3_600_000_000_000, 2) == 60_000_000_000  # 1 h: capped
    assert units_module.auto_slice_ns(0, 80_000_000_000, 2) == 10_000_000_000  # 4 per worker
    assert units_module.auto_slice_ns(0, 2_000_000_000, 8) == 1_000_000_000  # floor of 1 s
    assert units_module.auto_slice_ns(0, 9_000_000_000, 2, 1_010_000_000) == 2_000_000_000
    out = tmp_path / "auto"
    assert main(bag_command(drives[:1], out, "--slice", "auto", "--jobs", "2")) == 0
    with ResultsStore.open(out) as store:
        _, info = store.sequence_info("north")
        done = store.done_units("north")
    assert info["slice_ns"] == 2_000_000_000  # twice the default margin of 1.01 s
    assert main(bag_command(drives[:1], out, "--slice", "auto", "--resume")) == 0
    with ResultsStore.open(out) as store:
        assert store.done_units("north") == done  # same plan with one worker: nothing new
    assert main(bag_command(drives[:1], tmp_path / "bad", "--slice", "-1")) == 2
    assert "--slice" in capsys.readouterr().err


def test_scoring_threads_give_the_rows_of_one_thread(drives: list[Path]) -> None:
    """A unit scored with its methods on threads: the very rows of one thread."""
    plan = units_module.plan_bag(drives[0], "north", config(), 400_000_000)
    for unit in plan.units:
        alone = UnitRows.of(evaluate_unit(config(), unit, 1))
        threaded = UnitRows.of(evaluate_unit(config(), unit, 3))
        assert (threaded.frames, threaded.problems, threaded.messages) == (
            alone.frames,
            alone.problems,
            alone.messages,
        )
        for rows in ("frame_rows", "problem_rows", "count_rows", "methods", "criteria"):
            assert getattr(threaded.rows, rows) == getattr(alone.rows, rows), rows
    assert sum(len(UnitRows.of(evaluate_unit(config(), u)).rows.frame_rows) for u in plan.units)
    units_module.close_scoring_pools()


def test_read_ahead_yields_in_order_and_raises_where_the_source_did() -> None:
    def source() -> Iterator[int]:
        yield from range(50)
        raise InputError("bag is damaged after log time 49")

    taken: list[int] = []
    items = read_ahead(source(), depth=4)
    with pytest.raises(InputError, match="after log time 49"):
        taken.extend(items)
    assert taken == list(range(50))


def test_read_ahead_stops_its_thread_when_the_reader_stops() -> None:
    produced: list[int] = []

    def source() -> Iterator[int]:
        for item in range(1000):
            produced.append(item)
            yield item

    before = threading.active_count()
    items = read_ahead(source(), depth=4)
    assert next(items) == 0
    items.close()  # e.g. scoring raised: the bag must not be read on by a stray thread
    assert threading.active_count() == before
    assert len(produced) <= 1 + 4 + 1  # the one taken, the queue, the one waiting to go in


def test_work_alongside_runs_on_a_thread_after_the_workers_fork_and_raises_last(
    drives: list[Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """What runs alongside (the stream digests) starts once the pool forked; its error comes
    after every unit is written."""
    events: list[str] = []
    get_context = executors_module.multiprocessing.get_context

    def recorded(method: str) -> object:  # the pool is made here, its workers start right after
        alive = any(t.name == "dispeval-alongside" for t in threading.enumerate())
        events.append("pool made with the work running" if alive else "pool made")
        return get_context(method)

    monkeypatch.setattr(executors_module.multiprocessing, "get_context", recorded)
    threads: list[bool] = []

    def work() -> None:
        events.append("work")
        threads.append(threading.current_thread() is not threading.main_thread())
        raise InputError("cannot read the messages for their sha256")

    record = {**config().as_record(), "slice_ns": 200_000_000}
    with ResultsStore.create(tmp_path, record) as store:
        with pytest.raises(InputError, match="sha256"):
            evaluate_bags(drives, config(), store, jobs=2, slice_ns=200_000_000, alongside=work)
        planned = units_module.plan_bag(drives[0], "north", config(), 200_000_000).units
        assert len(store.done_units("north")) == len(planned)
    assert events == ["pool made", "work"]
    assert threads == [True]
