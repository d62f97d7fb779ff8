"""The results database's ``pairs`` and ``motion_pairs`` tables: pooled exactly, merged, kept.

A pair's sums are written with its unit and read back pooled by method, exactly the sums added
up here in plain numpy; ``merge`` copies them; a database without the tables reads as not
recorded (None), and merging one into results that have them drops them (never a part).
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pytest

from dispeval_ros.core.egomotion import BASE_COLUMNS, TemporalSums
from dispeval_ros.core.kernels.temporal import PAIR_COUNT
from dispeval_ros.core.records import FrameMotion, FramePair
from dispeval_ros.core.temporal import PRESETS, PairScores
from dispeval_ros.errors import InputError
from dispeval_ros.io.store import ResultsStore

CRITERIA = ("all", "interior")
THRESHOLDS = (0.5, 2.0, 4.0)


def pair(seed: int) -> PairScores:
    rng = np.random.default_rng(seed)
    preset = PRESETS["dispeval"]
    thresholds = np.array([1.0, *THRESHOLDS, np.inf, np.inf])[: PAIR_COUNT - 5]
    return PairScores(
        CRITERIA,
        preset.measures,
        rng.integers(0, 1000, (len(CRITERIA), PAIR_COUNT)).astype(np.float64) + 0.25,
        thresholds,
        "interpolate",
        preset,
    )


def motion(seed: int) -> TemporalSums:
    rng = np.random.default_rng(seed)
    width = len(BASE_COLUMNS) + len(THRESHOLDS)
    sums = rng.random((len(CRITERIA), width)) * 100
    return TemporalSums("egomotion", CRITERIA, THRESHOLDS, sums, (0.01 * seed,))


def write(folder: Path, sequence: str, seeds: range) -> ResultsStore:
    store = ResultsStore.create(folder, {"run": "test"})
    for unit, seed in enumerate(seeds):
        stamp = 100 * (seed + 1)
        store.add_unit(
            sequence,
            f"{unit:06d}",
            [],
            pairs=[FramePair(sequence, stamp, "sgbm", stamp - 100, pair(seed))],
            motion=[FrameMotion(sequence, stamp, "sgbm", stamp - 100, motion(seed))],
        )
    return store


def test_pairs_read_back_pooled_by_their_sums(tmp_path: Path) -> None:
    with write(tmp_path, "drive", range(4)) as store:
        pooled = store.pairs("drive")
        moved = store.motion_pairs("drive")
    assert pooled is not None
    assert moved is not None
    assert pooled["sgbm"].pairs == 4
    assert np.array_equal(pooled["sgbm"].sums, np.sum([pair(s).sums for s in range(4)], axis=0))
    count, sums = moved["sgbm"]
    assert count == 4
    assert np.array_equal(sums.sums, np.sum([motion(s).sums for s in range(4)], axis=0))
    assert sums.offsets == tuple(0.01 * s for s in range(4))


def test_merge_keeps_the_pairs_and_drops_them_when_a_part_has_none(tmp_path: Path) -> None:
    write(tmp_path / "a", "north", range(3)).close()
    write(tmp_path / "b", "south", range(3, 5)).close()
    with ResultsStore.create(tmp_path / "merged", {"run": "test"}) as merged:
        for part in ("a", "b"):
            with ResultsStore.open(tmp_path / part) as other:
                merged.add_results(other)
        assert merged.pairs("north")["sgbm"].pairs == 3  # type: ignore[index]
        assert merged.motion_pairs("south")["sgbm"][0] == 2  # type: ignore[index]
    write(tmp_path / "old", "east", range(2)).close()
    connection = sqlite3.connect(tmp_path / "old" / "results.sqlite")
    connection.execute("DROP TABLE motion_pairs")
    connection.commit()
    connection.close()
    with ResultsStore.open(tmp_path / "old") as old:
        assert old.motion_pairs("east") is None
        assert old.pairs("east") is not None
    with ResultsStore.create(tmp_path / "mixed", {"run": "test"}) as mixed:
        for part in ("a", "old"):
            with ResultsStore.open(tmp_path / part) as other:
                mixed.add_results(other)
        assert mixed.motion_pairs("north") is None  # not the residual of a part of the run
        assert mixed.pairs("north") is not None


def test_a_damaged_pair_or_motion_row_is_one_line_naming_the_database(tmp_path: Path) -> None:
    write(tmp_path, "drive", range(2)).close()
    connection = sqlite3.connect(tmp_path / "results.sqlite")
    connection.execute("UPDATE pairs SET sums = ? WHERE stamp = 100", (b"\0" * 8,))
    connection.execute("UPDATE motion_pairs SET criteria = '[]' WHERE stamp = 200")
    connection.commit()
    connection.close()
    with ResultsStore.open(tmp_path) as store:
        with pytest.raises(InputError, match=r"results\.sqlite: a stored pair row of sgbm is"):
            store.pairs("drive")
        with pytest.raises(InputError, match=r"a stored ego-motion row of sgbm is damaged"):
            store.motion_pairs("drive")


def test_restored_parts_that_do_not_fit_are_refused() -> None:
    good = pair(0)
    names, sums, levels = good.criteria, good.sums, good.thresholds
    again = PairScores.restored(names, sums.ravel(), levels, good.policy, good.preset.name)
    assert again.to_dict() == good.to_dict()
    for bad in [((), sums[:0], "dispeval"), (names, sums[:, 1:], "dispeval"), (names, sums, "x")]:
        with pytest.raises(ValueError, match=r"criteria, \d+ sums, preset"):
            PairScores.restored(bad[0], bad[1], levels, "interpolate", bad[2])
    moved = motion(1)
    restored = TemporalSums.of_pair(CRITERIA, THRESHOLDS, moved.sums.ravel(), 0.01)
    assert (restored.criteria, restored.thresholds, restored.offsets) == (
        CRITERIA,
        THRESHOLDS,
        (0.01,),
    )
    assert np.array_equal(restored.sums, moved.sums)
    for criteria, values in [((), moved.sums[:0]), (CRITERIA, moved.sums[:, 1:])]:
        with pytest.raises(ValueError, match=r"criteria, \d+ sums of \d+ columns"):
            TemporalSums.of_pair(criteria, THRESHOLDS, values, 0.01)
