"""``dispeval eval --out DIR``: the results folder of a bag run, for ``report`` and ``models``."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from refusal_support import assert_refused, snapshot

from dispeval_ros.cli.main import main
from dispeval_ros.io import list_frames
from dispeval_ros.io.store import FRAMES_CSV, RESULTS_FILE, SUMMARY_JSON, ResultsStore

SCENE = "sceneflow-flyingthings3d-seq"


@pytest.fixture(scope="module")
def estimates(shared_data: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Two noisy methods, one map per frame of the three-frame scene, named by the frame."""
    root = tmp_path_factory.mktemp("eval_out")
    made = {}
    for name, sigma in (("fine", 0.5), ("rough", 2.0)):
        folder = root / name
        folder.mkdir()
        for index, frame in enumerate(list_frames(shared_data / SCENE)):
            gt = np.where(frame.gt > 0, frame.gt, np.inf).astype(np.float32)
            noise = np.random.default_rng(index).normal(0, sigma, gt.shape)
            np.save(folder / f"{frame.frame}.npy", (gt + noise).astype(np.float32))
        made[name] = folder
    return made


def eval_args(shared_data: Path, estimates: dict[str, Path], *extra: str) -> list[str]:
    methods = [word for name, path in estimates.items() for word in ("--est", f"{name}={path}")]
    return ["eval", "--scene", str(shared_data / SCENE), *methods, *extra]


def eval_json(capsys: pytest.CaptureFixture[str], args: list[str]) -> dict:
    capsys.readouterr()
    assert main([*args, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_frames_csv_holds_the_numbers_eval_prints(
    shared_data: Path,
    estimates: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "out"
    printed = eval_json(capsys, eval_args(shared_data, estimates))
    assert eval_json(capsys, eval_args(shared_data, estimates, "--out", str(out))) == printed
    frames = [entry["frame"] for entry in printed["frames"]]
    stamps = {frame: index for index, frame in enumerate(dict.fromkeys(frames))}
    expected = {
        (str(stamps[entry["frame"]]), entry["method"], criterion): values
        for entry in printed["frames"]
        for criterion, values in entry["criteria"].items()
    }
    with open(out / FRAMES_CSV, newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert {row["sequence"] for row in rows} == {SCENE}
    assert len(rows) == len(expected)
    for row in rows:
        values = expected[(row["stamp"], row["method"], row["criterion"])]
        for measure, value in values.items():
            shown = row[measure]
            assert (math.isnan(value) and shown == "") or float(shown) == pytest.approx(
                value, rel=1e-12, abs=1e-12
            ), (row["stamp"], row["method"], row["criterion"], measure)


def test_the_folder_is_a_bag_run_folder_that_models_and_report_read(
    shared_data: Path,
    estimates: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "out"
    printed = eval_json(capsys, eval_args(shared_data, estimates, "--out", str(out)))
    summary = json.loads((out / SUMMARY_JSON).read_text())
    assert summary["provenance"] == printed["provenance"]
    (sequence,) = summary["sequences"]
    assert sequence["sequence"] == SCENE
    assert sequence["common_frames"] == 3
    assert {name: counts["matched"] for name, counts in sequence["counts"].items()} == {
        "fine": 3,
        "rough": 3,
    }
    totals = sequence["scores"]["fine"]["all"]["n"]
    assert totals == sum(
        e["criteria"]["all"]["n"] for e in printed["frames"] if e["method"] == "fine"
    )
    assert sequence["models"]["astar"] == ["fine"]
    with ResultsStore.open(out) as store:
        _, info = store.sequence_info(SCENE)
    assert [item["frame"] for item in info["frames"]] == ["0006", "0007", "0008"]
    capsys.readouterr()
    assert main(["models", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == sequence["models"]
    assert main(["report", str(out)]) == 0
    page = (out / "report.html").read_text(encoding="utf-8")
    # the header says what the scores are measured against (the scene's official maps)
    assert f"ground truth: scene {shared_data / SCENE} (official GT maps)" in page


def test_a_single_frame_folder_gives_the_models_eval_prints(
    shared_data: Path,
    estimates: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "out"
    args = eval_args(shared_data, estimates, "--frame", "0007", "--out", str(out))
    printed = eval_json(capsys, args)
    (sequence,) = json.loads((out / SUMMARY_JSON).read_text())["sequences"]
    assert sequence["models"] == printed["models"]
    assert [name.split(" @")[0] for name in sequence["objectives"]] == printed["objectives"]


def test_the_text_output_says_where_the_results_are(
    shared_data: Path,
    estimates: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "out"
    capsys.readouterr()
    assert main(eval_args(shared_data, estimates, "--out", str(out))) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    rows = len((out / FRAMES_CSV).read_text().splitlines()) - 1
    assert rows == 3 * 2 * 7  # frames × methods × criteria (all, 3 visibility, 3 depth)
    assert last == (
        f"results: {out / RESULTS_FILE} ({rows} rows; {out / FRAMES_CSV}, {out / SUMMARY_JSON})"
    )


def test_existing_results_and_protocol_runs_are_refused_leaving_the_folder(
    shared_data: Path,
    estimates: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "out"
    assert main(eval_args(shared_data, estimates, "--out", str(out))) == 0
    before = snapshot(tmp_path)
    capsys.readouterr()
    code = main(eval_args(shared_data, estimates, "--out", str(out)))
    assert_refused(code, capsys.readouterr().err, str(out), "already holds results")
    # refused before anything is read or scored: an unreadable estimate is not reached
    broken = {**estimates, "missing": tmp_path / "nowhere.pfm"}
    code = main(eval_args(shared_data, broken, "--out", str(out)))
    assert_refused(code, capsys.readouterr().err, str(out), "already holds results")
    code = main(
        eval_args(shared_data, estimates, "--out", str(tmp_path / "p"), "--protocol", "eth3d")
    )
    assert_refused(code, capsys.readouterr().err, "--out does not apply with --protocol")
    assert snapshot(tmp_path) == before
