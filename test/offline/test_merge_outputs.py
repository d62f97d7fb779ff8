"""``dispeval merge`` leaves the frames.csv and summary.json of one ``bag`` run over all bags."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from bag_support import bag_args
from refusal_support import assert_refused, snapshot

from dispeval_ros.cli.main import main
from dispeval_ros.io.store import FRAMES_CSV, RESULTS_FILE, SUMMARY_JSON
from dispeval_ros.offline.make_bag import synthetic_frames, write_bag


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Results of two short drives run apart, and of one run over both."""
    root = tmp_path_factory.mktemp("merge_outputs")
    bags = []
    for name, seed in (("north", 3), ("south", 4)):
        bags.append(root / name)
        write_bag(bags[-1], synthetic_frames(4, 96, 32, 10.0, seed=seed))
    results = {}
    for bag in bags:
        results[bag.name] = root / f"r_{bag.name}"
        assert main(bag_args(bag, results[bag.name], "--slice", "0.2")) == 0
    results["both"] = root / "r_both"
    both = bag_args(bags[0], results["both"], "--slice", "0.2")
    both.insert(2, str(bags[1]))
    assert main(both) == 0
    return results


def summary_of(folder: Path) -> dict[str, object]:
    document = json.loads((folder / SUMMARY_JSON).read_text())
    document.pop("provenance")  # how the results were made: a merge says so by design
    return document


def test_merged_frames_csv_is_the_inputs_frames_csv_one_after_the_other(
    runs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "merged"
    assert main(["merge", str(out), str(runs["north"]), str(runs["south"])]) == 0
    north, south = (
        (runs[name] / FRAMES_CSV).read_text().splitlines(keepends=True)
        for name in ("north", "south")
    )
    assert north[0] == south[0]
    assert len(north) > 1
    assert len(south) > 1
    merged = (out / FRAMES_CSV).read_text()
    assert merged == "".join(north + south[1:])
    assert merged == (runs["both"] / FRAMES_CSV).read_text()
    assert f"{len(north) + len(south) - 2} rows" in capsys.readouterr().out


def test_merged_summary_json_is_that_of_one_run_over_both_bags(
    runs: dict[str, Path], tmp_path: Path
) -> None:
    out = tmp_path / "merged"
    assert main(["merge", str(out), str(runs["north"]), str(runs["south"])]) == 0
    assert summary_of(out) == summary_of(runs["both"])
    assert [s["sequence"] for s in summary_of(out)["sequences"]] == ["north", "south"]
    provenance = json.loads((out / SUMMARY_JSON).read_text())["provenance"]
    merged = provenance["inputs"]["merged"]
    assert [item["results"] for item in merged] == [
        str(runs[name] / RESULTS_FILE) for name in ("north", "south")
    ]
    stored_in_inputs = [
        json.loads((runs[name] / SUMMARY_JSON).read_text())["provenance"]
        for name in ("north", "south")
    ]
    assert [item["provenance"] for item in merged] == stored_in_inputs


def test_merge_options_shape_the_summary_as_bag_options_do(
    runs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "merged_frames"
    options = ["--objectives", "frame", "--objective-measures", "bmp"]
    capsys.readouterr()
    assert (
        main(["merge", str(out), str(runs["north"]), str(runs["south"]), *options, "--json"]) == 0
    )
    printed = json.loads(capsys.readouterr().out)
    assert printed == json.loads((out / SUMMARY_JSON).read_text())
    assert printed["granularity"] == "frame"
    assert printed["objective_measures"] == ["bmp"]
    assert all("/bmp @" in name for name in printed["overall"]["objectives"])


def test_a_merge_refused_at_the_summary_writes_none_of_its_files(
    runs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "target" / "merged"
    out.parent.mkdir()
    before = snapshot(out.parent)
    capsys.readouterr()
    code = main(
        ["merge", str(out), str(runs["north"]), str(runs["south"]), "--objective-measures", "xyz"]
    )
    assert_refused(code, capsys.readouterr().err, "xyz")
    assert snapshot(out.parent) == before
