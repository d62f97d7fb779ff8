"""``dispeval bag --temporal``: the pairs of consecutive frames, exact across units.

A bag cut into many units and the same bag in one unit give the very same pair sums, and their
``tepe`` equals plain numpy written here from the definition (``|(E_t − E_t+1) − (D_t −
D_t+1)|`` over the pixels with GT in both frames) on the frames the bag was made of.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pytest
from bag_support import fast_rough_bag

from dispeval_ros.cli.main import main
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import synthetic_frames

FRAMES = 8


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str]]:
    """The drive's folder and its ``dispeval bag`` command line (``--out`` ROOT/res)."""
    root = tmp_path_factory.mktemp("pairs")
    _, args, _ = fast_rough_bag(root, FRAMES)
    return root, args


def run(drive: tuple[Path, list[str]], out: str, *extra: str) -> Path:
    root, args = drive
    command = [str(root / out) if a == str(root / "res") else a for a in args]
    assert main([*command, *extra]) == 0
    return root / out


def pair_rows(folder: Path) -> list[tuple]:
    connection = sqlite3.connect(folder / "results.sqlite")
    rows = connection.execute("SELECT * FROM pairs ORDER BY stamp, method").fetchall()
    connection.close()
    return rows


def numpy_tepe(root: Path, method: str) -> tuple[int, float]:
    """Pooled over the drive's pairs: (pixel pairs, tepe), from the maps the bag was made of."""
    gts = [
        np.asarray(frame.gt, dtype=np.float32)
        for frame in synthetic_frames(FRAMES, 192, 64, 10.0, seed=4)
    ]
    total, count = 0.0, 0
    for index in range(1, FRAMES):
        gt0, gt1 = (np.asarray(g, dtype=np.float64) for g in (gts[index - 1], gts[index]))
        est0 = np.load(root / method / f"{index - 1:06d}.npy").astype(np.float64)
        est1 = np.load(root / method / f"{index:06d}.npy").astype(np.float64)
        with np.errstate(invalid="ignore"):
            both = np.isfinite(gt0) & (gt0 > 0) & np.isfinite(gt1) & (gt1 > 0)
            error = np.abs((est0 - est1) - (gt0 - gt1))[both]
        total += float(error.sum())
        count += int(both.sum())
    return count, total / count


def test_many_units_give_the_pairs_of_one_and_numpy_s_tepe(drive: tuple[Path, list[str]]) -> None:
    root = drive[0]
    many = run(drive, "many", "--temporal", "--slice", "0.25")
    one = run(drive, "one", "--temporal", "--slice", "100")
    with ResultsStore.open(many) as store:
        units = len(store.done_units("drive"))
        pooled = store.pairs("drive")
    assert units >= 3  # the pairs at the units' edges are the ones at stake
    rows = pair_rows(many)
    assert rows == pair_rows(one)
    assert len(rows) == 2 * (FRAMES - 1)  # every consecutive pair of both methods
    assert pooled is not None
    for method in ("rough", "fine"):
        n, tepe = numpy_tepe(root, method)
        assert pooled[method].pairs == FRAMES - 1
        assert pooled[method]["all"]["n_pair"] == n
        assert pooled[method]["all"]["tepe"] == pytest.approx(tepe, rel=1e-5)


def test_without_temporal_nothing_is_paired(drive: tuple[Path, list[str]]) -> None:
    assert pair_rows(run(drive, "off", "--slice", "0.25")) == []
