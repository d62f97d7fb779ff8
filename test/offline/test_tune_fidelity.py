"""``dispeval tune --fidelity``: successive halving between whole A* groups (issue 25, part 2).

200 BM configurations (``--samples 200``) on the test-bed's synthetic drive (8 frames of
320 × 120, ``dispeval make-scene``), swept in full and in 3 rounds (2, 4, 8 frames). The full
sweep is the reference: the final first group must be its first group restricted to the kept
configurations, every member of its first group must have been kept, and the kept
configurations' rows must be its rows. Each round's cut is recomputed here from the stored
per-frame values with a plain numpy non-dominated sort written from the definition.
"""

from __future__ import annotations

import io
import itertools
import json
import math
import sqlite3
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np
import pytest
from refusal_support import assert_refused
from store_support import dump, units_stored

from dispeval_ros.cli import tune_cmd
from dispeval_ros.cli.main import main
from dispeval_ros.cli.progress import Progress
from dispeval_ros.io.store import RESULTS_FILE, SUMMARY_JSON
from dispeval_ros.offline.tuning.fidelity import keep_whole_groups, round_stamps

pytestmark = pytest.mark.slow

SPACE = Path(__file__).resolve().parents[2] / "config" / "tune_bm.yaml"  # 1 350 configurations
FRAMES = 8
ROUND_FRAMES = (2, 4, 8)  # ⌈8·2^(r−3)⌉


def run_json(*argv: str) -> dict:
    buffer = io.StringIO()
    with redirect_stdout(buffer):
        code = main(["tune", *argv, "--json", "--quiet"])
    assert code == 0
    return json.loads(buffer.getvalue())


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """The drive, the full sweep and the 3-round sweep of the same 200 configurations."""
    root = tmp_path_factory.mktemp("fidelity")
    with redirect_stdout(io.StringIO()):
        drive = root / "drive"
        assert main(["make-scene", str(drive), "--frames", str(FRAMES), "--width", "320",
                     "--height", "120"]) == 0  # fmt: skip
    scene = next(drive.glob("*/*_sync"))
    argv = ["--space", str(SPACE), "--scene", str(scene), "--samples", "200",
            "--seed", "3", "--criteria", "all"]  # fmt: skip
    multi = [*argv, "--fidelity", "3"]
    return {
        "root": root,
        "scene": scene,
        "argv": argv,
        "multi": multi,
        "full": run_json(*argv, "--out", str(root / "full")),
        "fidelity": run_json(*multi, "--out", str(root / "multi")),
    }


def group_1(doc: dict) -> set[str]:
    return {name for name, group in doc["models"]["groups"].items() if group == 1}


def stored(folder: Path) -> dict[tuple[int, str], tuple[object, ...]]:
    """(stamp, method) → the frame's row on criterion 'all'."""
    db = sqlite3.connect(folder / RESULTS_FILE)
    try:
        rows = db.execute("SELECT * FROM frames WHERE criterion = 'all'").fetchall()
        names = [d[0] for d in db.execute("SELECT * FROM frames LIMIT 0").description]
    finally:
        db.close()
    return {(r[1], r[2]): dict(zip(names, r, strict=True)) for r in rows}


def numpy_groups(matrix: np.ndarray) -> list[int]:
    """Non-dominated sorting from the definition (minimise; a dominates b: ≤ everywhere, < once)."""
    n = len(matrix)
    groups = [0] * n
    left = set(range(n))
    group = 0
    while left:
        group += 1
        front = [
            i
            for i in left
            if not any(
                np.all(matrix[j] <= matrix[i]) and np.any(matrix[j] < matrix[i]) for j in left
            )
        ]
        for i in front:
            groups[i] = group
        left -= set(front)
    return groups


def test_final_first_group_is_the_full_first_group_of_the_kept(runs: dict) -> None:
    kept = set(runs["fidelity"]["fidelity"]["kept"])
    assert len(runs["full"]["configurations"]) == 200
    assert set(runs["fidelity"]["models"]["groups"]) == kept
    assert group_1(runs["fidelity"]) == group_1(runs["full"]) & kept
    assert group_1(runs["full"]) <= kept  # every member of the full first group was kept
    assert len(kept) < 100


def test_kept_configurations_have_the_full_sweeps_rows_and_cut_ones_their_rounds(
    runs: dict,
) -> None:
    full, multi = stored(runs["root"] / "full"), stored(runs["root"] / "multi")
    report = runs["fidelity"]["fidelity"]
    last_of = {name: len(ROUND_FRAMES) for name in report["kept"]}
    for entry in report["rounds"]:
        last_of.update(dict.fromkeys(entry["cut"], entry["round"]))
    assert len(last_of) == 200
    expected = {
        (stamp, name) for name, last in last_of.items() for stamp in range(ROUND_FRAMES[last - 1])
    }
    assert set(multi) == expected
    assert all(multi[key] == full[key] for key in multi)


def test_each_cut_is_whole_groups_of_a_numpy_sort_on_the_rounds_frames(runs: dict) -> None:
    """Round r's objectives: sums over its frames of the stored per-frame values."""
    rows = stored(runs["root"] / "multi")
    measures = [name.split("/")[1].split(" @")[0] for name in runs["fidelity"]["objectives"]]
    report = runs["fidelity"]["fidelity"]
    scored = list(runs["fidelity"]["configurations"])
    for entry, frames in zip(report["rounds"], ROUND_FRAMES, strict=True):
        assert entry["frames"] == frames
        assert entry["configurations"] == len(scored)
        if entry["round"] == len(ROUND_FRAMES):
            assert entry["cut"] == []
            assert entry["kept"] == len(scored)
            assert sorted(scored) == sorted(report["kept"])
            break
        matrix = np.array(
            [[sum(rows[(s, name)][m] for s in range(frames)) for m in measures] for name in scored]
        )
        groups = numpy_groups(matrix)
        target = math.ceil(len(scored) / 2)
        kept_groups = 1
        while sum(g <= kept_groups for g in groups) < target:
            kept_groups += 1
        kept = [name for name, g in zip(scored, groups, strict=True) if g <= kept_groups]
        assert entry["kept"] == len(kept)
        assert entry["cut"] == [name for name in scored if name not in kept]
        scored = kept


def test_compute_is_counted_in_configuration_frames(runs: dict) -> None:
    report = runs["fidelity"]["fidelity"]
    rounds = report["rounds"]
    added = [ROUND_FRAMES[0], *(b - a for a, b in itertools.pairwise(ROUND_FRAMES))]
    spent = [r["configurations"] * n for r, n in zip(rounds, added, strict=True)]
    assert [r["configuration_frames"] for r in rounds] == spent
    assert report["configuration_frames"] == sum(spent) == len(stored(runs["root"] / "multi"))
    assert report["full_sweep_configuration_frames"] == 200 * FRAMES
    assert report["compute_fraction"] == sum(spent) / (200 * FRAMES)
    assert all(r["seconds"] > 0 for r in rounds)
    summary = json.loads((runs["root"] / "multi" / SUMMARY_JSON).read_text())
    assert summary["fidelity"]["rounds"] == rounds
    assert summary["overall"]["objectives"] == runs["fidelity"]["objectives"]


def test_printed_rounds(runs: dict, capsys: pytest.CaptureFixture[str]) -> None:
    out = runs["root"] / "printed"
    assert main(["tune", *runs["multi"], "--out", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    report = runs["fidelity"]["fidelity"]
    assert "multi-fidelity: 200 configurations in 3 rounds" in text
    for r in report["rounds"]:
        line = f"{r['round']}  {r['frames']:6d}  {r['configurations']:6d}  {r['kept']:4d}"
        assert line in text, text
    assert (
        f"compute: {report['configuration_frames']} configuration-frames of the full sweep's "
        f"{200 * FRAMES} ({report['compute_fraction']:.1%})" in " ".join(text.split())
    )


@pytest.mark.parametrize("stop_at", [3, 30])  # in round 1; in round 2
def test_an_interrupted_run_resumed_gives_the_same_database_and_cuts(
    runs: dict, stop_at: int, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = runs["root"] / f"interrupted{stop_at}"
    update = Progress.update
    calls = {"n": 0}

    def stop(self: Progress, done: int, total: int, frames: int) -> None:
        update(self, done, total, frames)
        calls["n"] += 1
        if calls["n"] == stop_at:
            raise KeyboardInterrupt

    monkeypatch.setattr(tune_cmd.Progress, "update", stop)
    assert main(["tune", *runs["multi"], "--out", str(out), "--quiet"]) == 130
    monkeypatch.undo()
    capsys.readouterr()
    resumed = run_json(*runs["multi"], "--out", str(out), "--resume")
    assert dump(out) == dump(runs["root"] / "multi")
    assert resumed["models"] == runs["fidelity"]["models"]
    for a, b in zip(
        resumed["fidelity"]["rounds"], runs["fidelity"]["fidelity"]["rounds"], strict=True
    ):
        assert (a["kept"], a["cut"]) == (b["kept"], b["cut"])
    assert resumed["units"]["skipped"] == stop_at


def test_hand_worked_rounds_and_cuts() -> None:
    # scenes of 3 and 1 frames: order (0,0), (1,0), (0,1), (0,2)
    assert round_stamps([3, 1], 2) == [[[0], [0]], [[0, 1, 2], [0]]]
    assert round_stamps([3, 1], 3) == [[[0], []], [[0], [0]], [[0, 1, 2], [0]]]
    groups = {"a": 1, "b": 2, "c": 2, "d": 3, "e": 4}
    assert keep_whole_groups(groups, list("abcde"), 0.5) == ["a", "b", "c"]  # 3 of 5, groups 1–2
    assert keep_whole_groups(groups, list("abcde"), 0.2) == ["a", "b", "c"]  # at least 2: group 2
    assert keep_whole_groups(groups, list("abcde"), 0.7) == ["a", "b", "c", "d"]
    assert keep_whole_groups({"a": 1, "b": 1, "c": 1}, list("abc"), 0.5) == ["a", "b", "c"]


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--fidelity", "1"], "--fidelity must be at least 2 rounds, got 1"),
        (["--fidelity", "3", "--keep", "1.5"], "--keep must be a fraction between 0 and 1, got 1.5"),
        (["--fidelity", "3", "--keep", "0"], "--keep must be a fraction between 0 and 1, got 0"),
        (["--keep", "0.5"], "--keep is the fraction kept by --fidelity rounds"),
        (["--fidelity", "5"], "--fidelity 5: the scenes hold 8 frame(s) in all, too few for 5 "
         "rounds that each add frames (at most 4)"),
    ],
)  # fmt: skip
def test_bad_options_are_one_line_and_leave_nothing(
    runs: dict, extra: list[str], needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out = runs["root"] / "refused"
    code = main(["tune", *runs["argv"], "--out", str(out), *extra])
    assert_refused(code, capsys.readouterr().err, needle)
    assert not out.exists()


def test_resume_with_other_rounds_is_refused(
    runs: dict, capsys: pytest.CaptureFixture[str]
) -> None:
    out = runs["root"] / "multi"
    before = dump(out)
    code = main(["tune", *runs["argv"], "--fidelity", "2", "--out", str(out), "--resume"])
    assert_refused(code, capsys.readouterr().err, "fidelity")
    assert dump(out) == before


def test_two_worker_processes_give_the_same_database(runs: dict) -> None:
    out = runs["root"] / "jobs2"
    doc = run_json(*runs["multi"], "--out", str(out), "--jobs", "2")
    assert dump(out) == dump(runs["root"] / "multi")
    assert doc["models"] == runs["fidelity"]["models"]


def test_a_run_killed_in_round_2_resumed_gives_the_same_database(runs: dict) -> None:
    """SIGKILL (one configuration a unit) after round 1's 200 units: same rows, same cuts."""
    import os
    import signal
    import subprocess
    import sys
    import time

    argv = [*runs["multi"], "--chunk", "1"]
    whole, killed = runs["root"] / "chunk1", runs["root"] / "killed"
    reference = run_json(*argv, "--out", str(whole))
    command = [sys.executable, "-m", "dispeval_ros", "tune", *argv, "--out", str(killed)]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while units_stored(killed) < 205 and process.poll() is None:
            assert time.monotonic() < deadline
            time.sleep(0.005)
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait()
    stored = units_stored(killed)
    rounds = reference["fidelity"]["rounds"]
    assert 205 <= stored < 200 + rounds[1]["configurations"], stored  # killed in round 2
    resumed = run_json(*argv, "--out", str(killed), "--resume")
    assert resumed["units"]["skipped"] == stored
    assert dump(killed) == dump(whole)
    assert [r["cut"] for r in resumed["fidelity"]["rounds"]] == [r["cut"] for r in rounds]
    assert resumed["models"] == reference["models"]


def test_a_local_dask_cluster_gives_the_same_database(runs: dict) -> None:
    pytest.importorskip("distributed")
    out = runs["root"] / "dask"
    doc = run_json(*runs["multi"], "--out", str(out), "--scheduler", "local:2")
    assert dump(out) == dump(runs["root"] / "multi")
    assert doc["models"] == runs["fidelity"]["models"]
