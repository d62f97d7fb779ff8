"""``dispeval tune`` on real MiddEval3 scenes: a 3 × 3 × 2 SGBM grid (issue 25's must-hold).

The maps are recomputed here with cv2 directly, from stereo_image_proc's definition of each
parameter (not through the project's StereoMethod), written as .npy files and scored with
``dispeval eval --out``: the sweep's database must hold the very same rows. Its models must be
those of ``dispeval models`` on the exported objectives; an interrupted run resumed, and a run
on two worker processes, must leave the same database as one uninterrupted run.
"""

from __future__ import annotations

import itertools
import json
import sqlite3
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from store_support import dump, units_stored

from dispeval_ros.cli import tune_cmd
from dispeval_ros.cli.main import main
from dispeval_ros.cli.progress import Progress
from dispeval_ros.io.store import RESULTS_FILE, ResultsStore

pytestmark = [pytest.mark.data, pytest.mark.slow]

SCENES = ("ArtL", "Teddy")
WINDOWS = (5, 7, 9)
UNIQUENESS = (5, 10, 15)
MODES = (0, 2)  # OpenCV StereoSGBM MODE_SGBM, MODE_SGBM_3WAY
SPACE = f"""
family: sgbm
parameters:
  correlation_window_size: {list(WINDOWS)}
  uniqueness_ratio: {list(UNIQUENESS)}
  sgbm_mode: {list(MODES)}
  disparity_range: 64
  P1: 200
  P2: 800
  speckle_size: 50
  speckle_range: 2
"""
# what the disparity node declares for the parameters the space leaves out
NODE_DEFAULTS = {"prefilter_cap": 31, "min_disparity": 0, "disp12_max_diff": 0}


def expected_configurations() -> dict[str, dict[str, int]]:
    """Name → node parameters of every grid point, in grid order (the last axis fastest)."""
    configurations = {}
    for window, uniqueness, mode in itertools.product(WINDOWS, UNIQUENESS, MODES):
        configurations[f"sgbm_w{window}_u{uniqueness}_mode{mode}"] = {
            **NODE_DEFAULTS,
            "correlation_window_size": window,
            "uniqueness_ratio": uniqueness,
            "sgbm_mode": mode,
            "disparity_range": 64,
            "P1": 200,
            "P2": 800,
            "speckle_size": 50,
            "speckle_range": 2,
        }
    return configurations


def node_map(left: np.ndarray, right: np.ndarray, p: dict[str, int]) -> np.ndarray:
    """The disparity stereo_image_proc publishes with SGBM set to ``p``: px, invalid = min − 1."""
    matcher = cv2.StereoSGBM.create(
        minDisparity=p["min_disparity"],
        numDisparities=p["disparity_range"],
        blockSize=p["correlation_window_size"],
        P1=p["P1"],
        P2=p["P2"],
        disp12MaxDiff=p["disp12_max_diff"],
        preFilterCap=p["prefilter_cap"],
        uniquenessRatio=p["uniqueness_ratio"],
        speckleWindowSize=p["speckle_size"],
        speckleRange=p["speckle_range"],
        mode=p["sgbm_mode"],
    )
    raw = matcher.compute(left, right)
    disparity = raw.astype(np.float32) / np.float32(16)
    disparity[raw < p["min_disparity"] * 16] = p["min_disparity"] - 1
    return disparity


def tune(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["tune", *argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.fixture(scope="module")
def sweep(shared_data: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """One uninterrupted sweep (``--json``): its folder, arguments and printed document."""
    root = tmp_path_factory.mktemp("tune")
    space = root / "space.yaml"
    space.write_text(SPACE)
    scenes = [shared_data / "middeval3-training-Q" / name for name in SCENES]
    argv = ["--space", str(space), *(a for s in scenes for a in ("--scene", str(s))), "--quiet"]
    out = root / "whole"
    import io
    from contextlib import redirect_stdout

    buffer = io.StringIO()
    with redirect_stdout(buffer):
        code = main(["tune", *argv, "--out", str(out), "--json"])
    assert code == 0
    return {
        "root": root,
        "argv": argv,
        "out": out,
        "scenes": scenes,
        "doc": json.loads(buffer.getvalue()),
    }


def frame_rows(folder: Path, sequence: str) -> list[tuple[object, ...]]:
    db = sqlite3.connect(folder / RESULTS_FILE)
    try:
        return db.execute(
            "SELECT * FROM frames WHERE sequence = ? ORDER BY stamp, method, criterion", (sequence,)
        ).fetchall()
    finally:
        db.close()


def test_database_holds_the_18_configurations_with_their_values(sweep: dict) -> None:
    expected = expected_configurations()
    with ResultsStore.open(sweep["out"]) as store:
        assert sorted(store.methods()) == sorted(expected)
        assert len(store.methods()) == 18
        assert store.sequences() == list(SCENES)
        assert store.config()["configurations"] == expected
    assert sweep["doc"]["configurations"] == expected


def test_scores_equal_dispeval_eval_of_the_same_opencv_maps(
    sweep: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for scene in sweep["scenes"]:
        left = cv2.cvtColor(cv2.imread(str(scene / "im0.png")), cv2.COLOR_BGR2GRAY)
        right = cv2.cvtColor(cv2.imread(str(scene / "im1.png")), cv2.COLOR_BGR2GRAY)
        estimates = []
        for name, parameters in expected_configurations().items():
            path = tmp_path / scene.name / f"{name}.npy"
            path.parent.mkdir(exist_ok=True)
            np.save(path, node_map(left, right, parameters))
            estimates += ["--est", f"{name}={path}"]
        out = tmp_path / f"eval-{scene.name}"
        assert main(["eval", "--scene", str(scene), *estimates, "--out", str(out)]) == 0
        capsys.readouterr()
        rows = frame_rows(out, scene.name)
        assert len(rows) == 18 * 7  # every method on the default partition's criteria
        assert frame_rows(sweep["out"], scene.name) == rows


def test_models_equal_dispeval_models_on_the_exported_objectives(
    sweep: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    exported = tmp_path / "objectives.csv"
    assert main(["models", str(sweep["out"]), "--export", str(exported)]) == 0
    capsys.readouterr()
    assert main(["models", str(exported), "--json"]) == 0
    models = json.loads(capsys.readouterr().out)
    assert sweep["doc"]["models"] == models
    header = exported.read_text().splitlines()[0].split(",")
    assert sweep["doc"]["objectives"] == header[1:]


def test_params_files_of_group_1_are_ros2_parameter_files(sweep: dict) -> None:
    groups = sweep["doc"]["models"]["groups"]
    first = sorted(name for name, group in groups.items() if group == 1)
    files = sorted(Path(p).stem for p in sweep["doc"]["params_files"])
    assert files == first
    expected = expected_configurations()
    for name in first:
        document = yaml.safe_load((sweep["out"] / "params" / f"{name}.yaml").read_text())
        parameters = document["disparity_node"]["ros__parameters"]
        assert parameters.pop("stereo_algorithm") == 1
        for key in ("uniqueness_ratio", "P1", "P2"):  # declared as doubles by the node
            assert isinstance(parameters[key], float)
        assert all(
            isinstance(v, int)
            for k, v in parameters.items()
            if k not in ("uniqueness_ratio", "P1", "P2")
        )
        assert parameters == {k: type(parameters[k])(v) for k, v in expected[name].items()}


def test_tune_csv_lists_every_configuration_with_its_group(sweep: dict) -> None:
    lines = (sweep["out"] / "tune.csv").read_text().splitlines()
    header = lines[0].split(",")
    assert header[:4] == ["method", "group", "reduced", "avg_rank"]
    rows = [dict(zip(header, line.split(","), strict=True)) for line in lines[1:]]
    groups = sweep["doc"]["models"]["groups"]
    assert {r["method"]: int(r["group"]) for r in rows} == groups
    expected = expected_configurations()
    for row in rows:
        assert (
            int(row["correlation_window_size"])
            == expected[row["method"]]["correlation_window_size"]
        )


def test_resume_after_an_interrupted_run_gives_the_same_database(
    sweep: dict, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = sweep["root"] / "interrupted"
    update = Progress.update

    def stop_after_two(self: Progress, done: int, total: int, frames: int) -> None:
        update(self, done, total, frames)
        if done == 2:
            raise KeyboardInterrupt

    monkeypatch.setattr(tune_cmd.Progress, "update", stop_after_two)
    code, _, err = tune(capsys, *sweep["argv"], "--out", str(out))
    assert code == 130, err
    with ResultsStore.open(out) as store:
        assert sum(len(store.done_units(s)) for s in SCENES) == 2
    monkeypatch.undo()
    code, text, err = tune(capsys, *sweep["argv"], "--out", str(out), "--resume")
    assert code == 0, err
    assert "4 units" in text
    assert "2 done before" in text
    assert dump(out) == dump(sweep["out"])


def test_two_worker_processes_give_the_same_database(
    sweep: dict, capsys: pytest.CaptureFixture[str]
) -> None:
    out = sweep["root"] / "jobs2"
    code, text, err = tune(capsys, *sweep["argv"], "--out", str(out), "--jobs", "2")
    assert code == 0, err
    assert dump(out) == dump(sweep["out"])
    assert "A* group" in text
    assert "sgbm_w5_u" in text


def test_a_search_wider_than_the_images_is_refused_before_anything_is_written(
    sweep: dict, capsys: pytest.CaptureFixture[str]
) -> None:
    from refusal_support import assert_refused

    space = sweep["root"] / "wide.yaml"
    space.write_text(
        "family: sgbm\nparameters: {correlation_window_size: [5, 7], disparity_range: 512}"
    )
    out = sweep["root"] / "wide"
    code, _, err = tune(
        capsys, "--space", str(space), "--scene", str(sweep["scenes"][0]), "--out", str(out)
    )
    assert_refused(code, err, "ArtL: images 347 px wide are too narrow", "sgbm_w5")
    assert not out.exists()
    code, _, err = tune(capsys, *sweep["argv"], "--out", str(out), "--objective-measures", "nope")
    assert_refused(code, err, "--objective-measures nope: not among the measures scored")
    assert not out.exists()


def test_printed_measures_equal_a_numpy_recomputation(sweep: dict) -> None:
    """tune.csv's SZE and BMPRE on 'all' over both scenes: sums of the per-scene definitions."""
    from reference import numpy_measures, valid_of

    from dispeval_ros.io import load_scene

    lines = (sweep["out"] / "tune.csv").read_text().splitlines()
    header = lines[0].split(",")
    rows = {r[0]: dict(zip(header, r, strict=True)) for r in (x.split(",") for x in lines[1:])}
    chosen = [lines[1].split(",")[0], lines[-1].split(",")[0], "sgbm_w7_u10_mode2"]
    totals = {name: {"sze": 0.0, "bmpre": 0.0} for name in chosen}
    for scene in sweep["scenes"]:
        loaded = load_scene(scene)  # the files as read; the measures are recomputed here
        left = cv2.cvtColor(cv2.imread(str(scene / "im0.png")), cv2.COLOR_BGR2GRAY)
        right = cv2.cvtColor(cv2.imread(str(scene / "im1.png")), cv2.COLOR_BGR2GRAY)
        for name in chosen:
            estimate = node_map(left, right, expected_configurations()[name])
            criteria = {"all": valid_of(loaded.gt)}
            values = numpy_measures(loaded.gt, estimate, criteria, "interpolate", loaded.camera)
            for measure in totals[name]:
                totals[name][measure] += values["all"][measure]
    for name in chosen:
        for measure, want in totals[name].items():
            have = float(rows[name][f"{measure} (all)"])
            assert have == pytest.approx(want, rel=1e-6), (name, measure)


def test_a_lidar_scene_is_scored_as_eval_scores_it(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A scan as GT: eval's metric depth ranges and depth measures, the same rows."""
    scene = shared_data / "kitti-lidar" / "stereo-rcnn-demo"
    space = tmp_path / "bm.yaml"
    space.write_text(
        "family: bm\nparameters: {correlation_window_size: [9, 15], disparity_range: 128}"
    )
    out = tmp_path / "tune"
    code, _, err = tune(
        capsys, "--space", str(space), "--scene", str(scene), "--out", str(out), "--quiet"
    )
    assert code == 0, err
    images = [cv2.imread(str(scene / name)) for name in ("left.png", "right.png")]
    left, right = (i if i.ndim == 2 else cv2.cvtColor(i, cv2.COLOR_BGR2GRAY) for i in images)
    estimates = []
    for window in (9, 15):  # the node's BM: its defaults for what the space leaves out
        bm = cv2.StereoBM.create(128, window)
        bm.setPreFilterSize(9)
        bm.setPreFilterCap(31)
        bm.setTextureThreshold(10)
        bm.setUniquenessRatio(15)
        bm.setSpeckleWindowSize(100)
        bm.setSpeckleRange(4)
        raw = bm.compute(left, right)
        disparity = raw.astype(np.float32) / 16
        disparity[raw < 0] = -1
        path = tmp_path / f"bm_w{window}.npy"
        np.save(path, disparity)
        estimates += ["--est", f"bm_w{window}={path}"]
    assert main(["eval", "--scene", str(scene), *estimates, "--out", str(tmp_path / "eval")]) == 0
    capsys.readouterr()
    rows = frame_rows(tmp_path / "eval", scene.name)
    assert rows
    assert frame_rows(out, scene.name) == rows
    with ResultsStore.open(out) as store:
        assert store.config()["depth_ranges"] == "0-10,10-30,30-inf"


def test_a_local_dask_cluster_gives_the_same_database(
    sweep: dict, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("distributed")
    out = sweep["root"] / "dask"
    code, _, err = tune(capsys, *sweep["argv"], "--out", str(out), "--scheduler", "local:2")
    assert code == 0, err
    assert dump(out) == dump(sweep["out"])


def test_resume_after_a_kill_gives_the_same_database(
    sweep: dict, capsys: pytest.CaptureFixture[str]
) -> None:
    """SIGKILL mid-sweep (one configuration a unit): the resumed database is the whole run's."""
    import os
    import signal
    import subprocess
    import sys
    import time

    argv = [*sweep["argv"], "--chunk", "1"]
    whole, killed = sweep["root"] / "chunk1", sweep["root"] / "killed"
    code, _, err = tune(capsys, *argv, "--out", str(whole))
    assert code == 0, err
    command = [sys.executable, "-m", "dispeval_ros", "tune", *argv, "--out", str(killed)]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while units_stored(killed) < 3 and process.poll() is None:
            assert time.monotonic() < deadline
            time.sleep(0.01)
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait()
    stored = units_stored(killed)
    assert 3 <= stored < 36, stored  # killed mid-sweep
    code, text, err = tune(capsys, *argv, "--out", str(killed), "--resume")
    assert code == 0, err
    assert f"{stored} done before" in text
    assert dump(killed) == dump(whole)


def test_the_readme_example_prints_what_the_readme_shows(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The README's command (its paths from the project root) prints its table and YAML."""
    import io
    from contextlib import redirect_stdout

    from test_readme import CLONE, readme_block

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("COLUMNS", "100")
    scenes = shared_data / "middeval3-training-Q"
    argv = ["--space", str(CLONE / "config" / "tune_sgbm.yaml"), "--out", "tune-sgbm", "--quiet"]
    buffer = io.StringIO()
    with redirect_stdout(buffer):
        assert (
            main(["tune", *argv, "--scene", str(scenes / "ArtL"), "--scene", str(scenes / "Teddy")])
            == 0
        )
    assert buffer.getvalue() == readme_block("tune-output", "text")
    written = (tmp_path / "tune-sgbm" / "params" / "sgbm_w5_u10_mode0.yaml").read_text()
    assert written == readme_block("tune-params", "yaml")


def test_a_seeded_sample_of_the_grid_is_stored_with_its_seed(
    sweep: dict, capsys: pytest.CaptureFixture[str]
) -> None:
    out = sweep["root"] / "sampled"
    argv = ["--space", sweep["argv"][1], "--scene", str(sweep["scenes"][0]), "--quiet"]
    code, text, err = tune(capsys, *argv, "--out", str(out), "--samples", "5", "--seed", "3")
    assert code == 0, err
    assert "5 configurations of sgbm on 1 scene" in text
    with ResultsStore.open(out) as store:
        config = store.config()
        assert (config["samples"], config["seed"]) == (5, 3)
        assert set(store.methods()) == set(config["configurations"])
        assert set(store.methods()) < set(expected_configurations())
        assert config["configurations"] == {
            m: expected_configurations()[m] for m in store.methods()
        }


def test_a_dataset_tree_is_swept_scene_by_scene(
    sweep: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A folder of scenes (and of other things) gives its scenes, in order: the same rows."""
    tree = tmp_path / "dataset"
    tree.mkdir()
    for scene in sweep["scenes"]:
        (tree / scene.name).symlink_to(scene, target_is_directory=True)
    (tree / "notes").mkdir()  # not a scene: passed over
    space = sweep["root"] / "space.yaml"
    out = tmp_path / "tree"
    code, _, err = tune(
        capsys, "--space", str(space), "--scene", str(tree), "--out", str(out), "--quiet"
    )
    assert code == 0, err
    with ResultsStore.open(out) as store:
        assert store.sequences() == list(SCENES)
    for sequence in SCENES:
        assert frame_rows(out, sequence) == frame_rows(sweep["out"], sequence)
    empty = tmp_path / "empty"
    (empty / "notes").mkdir(parents=True)
    code, _, err = tune(
        capsys, "--space", str(space), "--scene", str(empty), "--out", str(tmp_path / "none")
    )
    assert code == 2
    assert "not a recognised scene folder" in err
    assert "nor a dataset tree" in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "none").exists()
