"""Planning is bounded by a bag's messages, not its time span; ``--resume`` knows a bag by path.

A robot without a real-time clock logs its first messages at 1970 and the rest once NTP set
the clock (2023): 53 years of log time cut into 1 s slices were 1.7·10⁹ units (MemoryError).
"""

from __future__ import annotations

import dataclasses
import itertools
import os
import resource
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from bag_support import METHODS, as_ros1, bag_args

from dispeval_ros.cli.main import main
from dispeval_ros.io.bags import BagSource
from dispeval_ros.offline import units as units_module
from dispeval_ros.offline.make_bag import (
    START_NS,
    StreamStamps,
    bag_config,
    synthetic_frames,
    write_bag,
)

EARLY, LATE = 3, 5
"""Frames logged about 1 s after the epoch (no RTC yet), then once the clock was set."""
FRAMES = EARLY + LATE


def write_jumped(path: Path, storage: str) -> Path:
    """A drive of :data:`FRAMES` frames whose log time jumps from 1970 to 2023 after EARLY."""
    frames = []
    for index, frame in enumerate(synthetic_frames(FRAMES, 192, 64, 10.0, seed=5)):
        base = 1_000_000_000 if index < EARLY else START_NS - EARLY * 100_000_000
        stamp = base + index * 100_000_000
        frames.append(dataclasses.replace(frame, stamps=StreamStamps(stamp, stamp, stamp, stamp)))
    write_bag(path, frames, storage=storage)
    return path


@pytest.fixture(scope="module", params=["rosbag2-sqlite3", "rosbag2-mcap", "mcap", "ros1"])
def jumped(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The jumped drive in rosbag2 (sqlite3, MCAP), ROS 1 (read by rosbags) and plain MCAP."""
    root = tmp_path_factory.mktemp("jumped")
    if request.param == "ros1":
        as_ros1(write_jumped(root / "drive2", "rosbag2-sqlite3"), root / "drive.bag")
        return root / "drive.bag"
    name = "drive.mcap" if request.param == "mcap" else "drive"
    return write_jumped(root / name, request.param)


def test_log_times_are_those_of_the_messages(jumped: Path) -> None:
    """What planning reads from each reader's index is every message's log time."""
    with BagSource(jumped) as source:
        read = sorted(log_ns for _, log_ns, _ in source.messages(list(source.topics)))
        assert sorted(source.log_times()) == read
        assert len(read) == source.message_count


PLAN = """
import sys
from pathlib import Path
from dispeval_ros.offline import units
from dispeval_ros.offline.make_bag import bag_config
config = bag_config({methods!r})
source = units.open_bag(Path(sys.argv[1]))
plan = units.plan_bag(Path(sys.argv[1]), "drive", config, 1_000_000_000)
print(len(plan.units), units.auto_slice_for(source, 2, config.tolerance_ns + config.lateness_ns))
"""


def _limit_memory() -> None:
    limit = 3 << 30  # far above what planning needs, far below 1.7·10⁹ units
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def test_a_jumped_clock_plans_a_few_units_in_bounded_memory(jumped: Path) -> None:
    """Units only where messages are (two regions): a few, planned in bounded memory and time.

    In a child process limited to 3 GB and 120 s, as a span-sized plan exhausts either.
    """
    child = subprocess.run(
        [sys.executable, "-c", PLAN.format(methods=METHODS), str(jumped)],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=_limit_memory,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
        check=False,
    )
    assert child.returncode == 0, child.stderr[-2000:]
    count, auto = map(int, child.stdout.split())
    assert 2 <= count <= 4  # one or two slices of 1 s per occupied region
    assert auto < units_module.AUTO_SLICE_BOUNDS_NS[1]  # from the seconds the messages fill


def test_units_of_a_jumped_clock_partition_all_time(jumped: Path) -> None:
    """Named by slice index, contiguous from the first to the last, with no empty region."""
    plan = units_module.plan_bag(jumped, "drive", bag_config(METHODS), 1_000_000_000)
    units = plan.units
    assert units[0].start_ns == -(2**62)
    assert units[-1].stop_ns == 2**62
    assert all(a.stop_ns == b.start_ns for a, b in itertools.pairwise(units))
    assert len({unit.name for unit in units}) == len(units)
    assert units[1].start_ns > START_NS - 10**9  # the 53 years are in the first unit
    assert plan == units_module.plan_bag(jumped, "drive", bag_config(METHODS), 1_000_000_000)


def scores(out: Path) -> tuple[list[tuple[object, ...]], list[tuple[object, ...]]]:
    """The frames stored (stamp, method) and the match counts of a results folder."""
    with sqlite3.connect(out / "results.sqlite") as connection:
        frames = connection.execute(
            "SELECT DISTINCT stamp, method FROM frames ORDER BY stamp, method"
        ).fetchall()
        counts = connection.execute(
            "SELECT method, matched, unmatched, dropped, failed FROM match_counts ORDER BY method"
        ).fetchall()
    return frames, counts


@pytest.mark.parametrize("extra", [("--slice", "1"), ("--slice", "auto"), ("--jobs", "2")])
def test_a_jumped_clock_scores_every_frame(
    jumped: Path, tmp_path: Path, extra: tuple[str, ...]
) -> None:
    """Every frame of both regions is scored once by every method, the counts adding up."""
    out = tmp_path / "out"
    assert main(bag_args(jumped, out, *extra)) == 0
    frames, counts = scores(out)
    assert len(frames) == FRAMES * len(METHODS)
    early = sorted({stamp for stamp, _ in frames})[:EARLY]
    assert all(stamp < 10**10 for stamp in early)  # the 1970 frames are among them
    assert counts == [(method, FRAMES, 0, 0, 0) for method in sorted(METHODS)]


def test_resume_knows_the_bag_however_its_path_is_spelled(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Started with ``bags/x``: resumes with the absolute path and ``./bags/x``; another bag
    (a copy elsewhere) is refused in one line."""
    monkeypatch.chdir(tmp_path)
    bag = write_jumped(Path("bags") / "drive.mcap", "mcap")
    out = Path("out")
    assert main(bag_args(bag, out, "--slice", "1")) == 0
    first = scores(out)
    for spelling in (bag.resolve(), Path(".") / "bags" / "drive.mcap"):
        assert main(bag_args(Path(str(spelling)), out, "--slice", "1", "--resume")) == 0
        assert scores(out) == first
    capsys.readouterr()
    other = Path("elsewhere") / "drive.mcap"
    other.parent.mkdir()
    shutil.copy(bag, other)
    assert main(bag_args(other, out, "--slice", "1", "--resume")) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1, error
    assert "'bags'" in error, error


def stored_bags(out: Path) -> str:
    with sqlite3.connect(out / "results.sqlite") as connection:
        (value,) = connection.execute("SELECT value FROM run WHERE key = 'bags'").fetchone()
    connection.close()
    return str(value)


def test_resume_of_an_older_database_that_stored_the_path_as_typed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """An older dispeval stored ``bags/drive.mcap`` as typed. From the folder it ran in, any
    spelling of that bag resumes (the record keeps the old spelling); from another folder the
    relative path names another file, and one line says where to resume from."""
    monkeypatch.chdir(tmp_path)
    bag = write_jumped(Path("bags") / "drive.mcap", "mcap")
    out = Path("out")
    assert main(bag_args(bag, out, "--slice", "1")) == 0
    first = scores(out)
    absolute = stored_bags(out)
    as_typed = absolute.replace(str(bag.resolve()), str(bag))
    assert as_typed != absolute
    with sqlite3.connect(out / "results.sqlite") as connection:
        connection.execute("UPDATE run SET value = ? WHERE key = 'bags'", (as_typed,))
    connection.close()
    for spelling in (bag.resolve(), bag):
        assert main(bag_args(spelling, out, "--slice", "1", "--resume")) == 0
        assert scores(out) == first
        assert stored_bags(out) == as_typed
    capsys.readouterr()
    monkeypatch.chdir(tmp_path / "bags")
    assert main(bag_args(tmp_path / bag, tmp_path / out, "--slice", "1", "--resume")) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1, error
    assert "names bag 'bags/drive.mcap' as typed" in error, error
    assert "run --resume from that folder" in error, error
    assert scores(tmp_path / out) == first
