"""``dispeval bag --temporal``: the pairs of consecutive frames, exact across units.

A bag cut into many units and the same bag in one unit give the very same pair sums, and their
``tepe`` equals plain numpy written here from the definition (``|(E_t − E_t+1) − (D_t −
D_t+1)|`` over the pixels with GT in both frames) on the frames the bag was made of.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import pytest
from bag_support import fast_rough_bag, numpy_pair_errors

from dispeval_ros.cli.main import main
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.summary import objective_table

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
    errors = numpy_pair_errors(root, method, FRAMES, 192, 64)
    count = sum(error.size for error in errors)
    total = sum(float(error.sum()) for error in errors)
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


def test_summary_json_tables_and_objectives_carry_the_pooled_pairs(
    drive: tuple[Path, list[str]], capsys: pytest.CaptureFixture[str]
) -> None:
    out = run(drive, "objectives", "--temporal", "--objective-measures", "sze", "tepe")
    text = capsys.readouterr().out
    assert "temporal consistency (--temporal dispeval" in text
    assert "rough 7 pairs, fine 7 pairs" in " ".join(text.split())
    document = json.loads((out / "summary.json").read_text())
    [sequence] = document["sequences"]
    assert sequence["objectives"] == ["all/sze @drive", "all/tepe @drive"]
    with ResultsStore.open(out) as store:
        pooled = store.pairs("drive")
        methods, names, matrix = objective_table(store, ["tepe"])
    assert pooled is not None
    assert names == ["all/tepe @drive"]
    for row, method in enumerate(methods):
        entry = sequence["temporal"][method]
        assert entry["pairs"] == FRAMES - 1
        assert entry["criteria"]["all"]["tepe"] == pooled[method]["all"]["tepe"]
        assert matrix[row, 0] == pooled[method]["all"]["tepe"]


def test_pair_objectives_need_temporal_one_line(
    drive: tuple[Path, list[str]], capsys: pytest.CaptureFixture[str]
) -> None:
    root, args = drive
    command = [str(root / "refused") if a == str(root / "res") else a for a in args]
    assert main([*command, "--objective-measures", "tepe"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "pair measures need --temporal" in err


def test_merge_and_resume_keep_the_pairs(
    drive: tuple[Path, list[str]], monkeypatch: pytest.MonkeyPatch
) -> None:
    from dispeval_ros.offline import units as units_module

    root = drive[0]
    whole = run(drive, "whole", "--temporal", "--slice", "0.25")
    evaluate_unit = units_module.evaluate_unit

    def failing(config, unit, threads=1):  # type: ignore[no-untyped-def]
        if unit.name == "000002":
            raise RuntimeError("out of cheese")
        return evaluate_unit(config, unit, threads)

    monkeypatch.setattr(units_module, "evaluate_unit", failing)
    resumed = run(drive, "resumed", "--temporal", "--slice", "0.25")
    assert len(pair_rows(resumed)) < len(pair_rows(whole))  # the failed unit's pairs missing
    monkeypatch.setattr(units_module, "evaluate_unit", evaluate_unit)
    run(drive, "resumed", "--temporal", "--slice", "0.25", "--resume")
    assert pair_rows(resumed) == pair_rows(whole)
    merged = root / "merged"
    assert main(["merge", str(merged), str(whole)]) == 0
    assert pair_rows(merged) == pair_rows(whole)


def test_a_database_older_than_the_pairs_table_reads_as_not_recorded(
    drive: tuple[Path, list[str]],
) -> None:
    from dispeval_ros.cli.summary import NO_PAIRS, run_summary_text
    from dispeval_ros.summary import summarize

    out = run(drive, "older", "--temporal")
    connection = sqlite3.connect(out / "results.sqlite")
    connection.execute("DROP TABLE pairs")
    connection.commit()
    connection.close()
    with ResultsStore.open(out) as store:
        assert store.pairs("drive") is None
        summary = summarize(store)
    assert summary.to_dict()["sequences"][0]["temporal"] is None
    assert NO_PAIRS.split("(")[0] in run_summary_text(summary)


def test_a_sequence_of_one_frame_says_no_pair(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, args, _ = fast_rough_bag(tmp_path, 1)
    assert main([*args, "--temporal"]) == 0
    assert "temporal: no pair (no method has an estimate of two consecutive frames)" in (
        " ".join(capsys.readouterr().out.split())
    )
    document = json.loads((tmp_path / "res" / "summary.json").read_text())
    assert document["sequences"][0]["temporal"] == {}
    assert pair_rows(tmp_path / "res") == []
