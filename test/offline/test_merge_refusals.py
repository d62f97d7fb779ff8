"""``dispeval merge`` refusals leave OUT as it was; damaged inputs are refused with one line."""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import pytest
from bag_support import bag_args
from refusal_support import assert_refused, snapshot

from dispeval_ros.cli.main import main
from dispeval_ros.io.store import RESULTS_FILE
from dispeval_ros.offline.make_bag import synthetic_frames, write_bag


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Results of two short drives, and of the first one again from a copy of its bag."""
    root = tmp_path_factory.mktemp("runs")
    for name, seed in (("north", 3), ("south", 4)):
        write_bag(root / name, synthetic_frames(4, 96, 32, 10.0, seed=seed))
    shutil.copytree(root / "north", root / "elsewhere" / "north")
    made = {"north": root / "north", "south": root / "south", "copy": root / "elsewhere" / "north"}
    results = {}
    for name, bag in made.items():
        results[name] = root / f"r_{name}"
        assert main(bag_args(bag, results[name], "--slice", "0.2")) == 0
    return results


def damaged(runs: dict[str, Path], tmp_path: Path, how: str) -> Path:
    """A copy of north's results damaged ``how``."""
    folder = tmp_path / f"damaged_{how}"
    folder.mkdir()
    target = folder / RESULTS_FILE
    original = (runs["north"] / RESULTS_FILE).read_bytes()
    if how == "garbage":
        target.write_bytes(b"\x5a" * 8192)
    elif how == "truncated":
        target.write_bytes(original[: len(original) // 2])
    elif how == "overwritten":  # header and table list intact, pages further in wrecked
        target.write_bytes(original[:8192] + b"\xff" * (len(original) - 8192))
    else:  # a table dropped
        target.write_bytes(original)
        connection = sqlite3.connect(target)
        connection.execute("DROP TABLE problems")
        connection.commit()
        connection.close()
    return folder


def refused_leaves_nothing(
    capsys: pytest.CaptureFixture[str], out: Path, *inputs: Path, needle: str
) -> None:
    """Refused with one line; OUT's folder (no OUT, no scratch folder) and inputs as they were."""
    out.parent.mkdir(exist_ok=True)
    before = snapshot(out.parent), [(path / RESULTS_FILE).read_bytes() for path in inputs]
    capsys.readouterr()
    code = main(["merge", str(out), *map(str, inputs)])
    assert_refused(code, capsys.readouterr().err, needle)
    assert (snapshot(out.parent), [(path / RESULTS_FILE).read_bytes() for path in inputs]) == before


@pytest.mark.parametrize("case", ["twice", "sequence_from_two_bags"])
def test_a_refused_merge_leaves_no_results_and_the_corrected_one_runs(
    runs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    out = tmp_path / "target" / "merged"
    second = runs["north"] if case == "twice" else runs["copy"]
    needle = "count it twice" if case == "twice" else "sequence north comes from"
    refused_leaves_nothing(capsys, out, runs["north"], runs["south"], second, needle=needle)
    assert main(["merge", str(out), str(runs["north"]), str(runs["south"])]) == 0
    assert "2 sequences" in capsys.readouterr().out


def test_a_refused_merge_leaves_existing_results_untouched(
    runs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "target" / "merged"
    assert main(["merge", str(out), str(runs["north"])]) == 0
    for inputs in ([runs["south"]], [runs["south"], runs["south"]]):
        refused_leaves_nothing(capsys, out, *inputs, needle=str(out))


@pytest.mark.parametrize("how", ["garbage", "truncated", "overwritten", "no_table"])
def test_a_damaged_results_database_is_refused_naming_it(
    runs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], how: str
) -> None:
    bad = damaged(runs, tmp_path, how)
    out = tmp_path / "target" / "merged"
    refused_leaves_nothing(capsys, out, runs["south"], bad, needle=str(bad / RESULTS_FILE))
