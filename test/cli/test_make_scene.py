"""``dispeval make-scene``: the synthetic drive as a KITTI raw drive with exact GT and motion.

``eval --scene`` of what it writes runs with ``--temporal`` and ``--egomotion``: the true
disparity (the drive's own GT maps) has TEPE 0 and, on the static drive, an ego-motion
residual below 0.1 px; the poses read back by the devkit's convention are the rig's motion.
"""

from __future__ import annotations

import dataclasses
import json
import shlex
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from test_readme import README, readme_block

from dispeval_ros.cli.main import main
from dispeval_ros.core.transforms import invert_rigid
from dispeval_ros.io import read_disparity
from dispeval_ros.io.kitti_raw import camera_poses, open_drive
from dispeval_ros.offline.make_drive import DAY, DRIVE, GT_FOLDER
from dispeval_ros.testbed import driving_setup, driving_world_at, render_stereo

FRAMES, WIDTH, HEIGHT = 4, 320, 96


def make(root: Path, *extra: str) -> Path:
    out = root / "scene"
    assert main(["make-scene", str(out), "--frames", str(FRAMES), "--width", str(WIDTH),
                 "--height", str(HEIGHT), "--json", *extra]) == 0  # fmt: skip
    return out


@pytest.fixture(scope="module")
def static(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The drive without traffic: every surface static."""
    return make(tmp_path_factory.mktemp("static"), "--no-traffic")


def evaluate(out: Path, capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    drive = out / DAY / DRIVE
    capsys.readouterr()
    code = main([
        "eval", "--scene", str(drive), "--est", f"true={drive / GT_FOLDER}",
        "--est", f"sgbm={out / 'estimates' / 'sgbm'}", "--temporal", "--egomotion", "--json",
    ])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    result: dict[str, Any] = json.loads(captured.out)
    return result


def test_the_true_disparity_has_tepe_0_and_a_residual_below_a_tenth_of_a_pixel(
    static: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    result = evaluate(static, capsys)
    temporal = result["temporal"]["methods"]
    assert temporal["true"]["pairs"] == FRAMES - 1
    for criterion, values in temporal["true"]["criteria"].items():
        assert values["n_pair"] > 0, criterion
        assert values["tepe"] == 0.0, criterion
    assert temporal["sgbm"]["criteria"]["all"]["tepe"] > 0.1
    motion = result["egomotion"]["methods"]
    assert motion["true"]["pairs"] == FRAMES - 1
    true, sgbm = (motion[m]["criteria"]["gtfree:all"] for m in ("true", "sgbm"))
    assert true["n_residual"] > 0.5 * WIDTH * HEIGHT
    assert true["mean_abs"] < 0.1
    assert true["bad_0.5"] < 1.0
    assert sgbm["mean_abs"] > 5 * true["mean_abs"]
    assert all(abs(offset) < 0.05 for offset in motion["true"]["offsets"])


def test_the_poses_are_the_rigs_motion_and_the_gt_its_exact_disparity(static: Path) -> None:
    drive = open_drive(static / DAY / DRIVE)
    assert drive.frames == [f"{i:010d}" for i in range(FRAMES)]
    poses = camera_poses(drive)
    world, rig = driving_setup(WIDTH, HEIGHT, 10.0, 0)
    world = dataclasses.replace(world, boxes=())  # --no-traffic
    start = driving_world_at(world, rig, 0.0)[1].position
    for index in range(FRAMES):
        world_t, rig_t = driving_world_at(world, rig, index / 10.0)
        moved = invert_rigid(poses[0]) @ poses[index]  # type: ignore[operator]
        step = np.subtract(rig_t.position, start)
        np.testing.assert_allclose(moved[:3, :3], np.eye(3), atol=1e-12)
        # camera axes: x right, y down, z forward; the world's y is up
        np.testing.assert_allclose(moved[:3, 3], (step[0], -step[1], step[2]), atol=1e-6)
        if index == FRAMES - 1:
            exact = render_stereo(world_t, rig_t, stamp=index / 10.0).gt_left
            stored = read_disparity(drive.folder / GT_FOLDER / f"{index:010d}.png")
            valid = np.isfinite(exact)
            assert np.array_equal(np.isfinite(stored) & (stored > 0), valid)
            assert np.abs(stored[valid] - exact[valid]).max() <= 1 / 512 + 1e-6
    camera = drive.calibration.camera
    assert (camera.f, camera.baseline) == pytest.approx((rig.f, rig.baseline), rel=1e-12)
    assert drive.calibration.ros_view()[1:] == pytest.approx((rig.cx, rig.cy), rel=1e-12)


def test_with_traffic_it_runs_and_the_true_disparity_still_has_tepe_0(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    result = evaluate(make(tmp_path), capsys)
    assert result["temporal"]["methods"]["true"]["criteria"]["all"]["tepe"] == 0.0
    motion = result["egomotion"]["methods"]["true"]["criteria"]["gtfree:all"]
    assert motion["n_moving"] > 0  # the traffic: pixels the photometric check masks


def test_bad_input_is_one_line_and_leaves_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "taken"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert main(["make-scene", str(out), "--frames", "1"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "exists" in line
    assert (out / "keep.txt").read_text() == "mine"
    for bad in (["--frames", "0"], ["--width", "10"], ["--fps", "nan"]):
        assert main(["make-scene", str(tmp_path / "new"), *bad]) == 2
        assert len(capsys.readouterr().err.strip().splitlines()) == 1, bad
    assert not (tmp_path / "new").exists()
    # a GT disparity KITTI's PNG cannot hold (above 255.99 px): nothing half-written stays
    assert main(["make-scene", str(tmp_path / "wide"), "--frames", "1", "--width", "4000",
                 "--height", "32", "--json"]) == 2  # fmt: skip
    assert "KITTI PNG encodes disparities up to" in capsys.readouterr().err
    assert not (tmp_path / "wide").exists()


@pytest.mark.slow
def test_the_readme_example_prints_the_readme_numbers(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    make_line, eval_line = readme_block("make-scene-example", "bash").strip().splitlines()
    monkeypatch.chdir(tmp_path)
    assert main(shlex.split(make_line)[1:]) == 0
    capsys.readouterr()
    assert main([*shlex.split(eval_line)[1:], "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    text = README.read_text(encoding="utf-8")
    after = text[text.index("<!-- /make-scene-example -->") :]
    rows = {
        line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
        for line in after[: after.index("\n#")].splitlines()
        if line.startswith(("| true ", "| sgbm ", "| bm_fast "))
    }
    assert list(rows) == ["true", "sgbm", "bm_fast"]
    for method, cells in rows.items():
        temporal = document["temporal"]["methods"][method]
        motion = document["egomotion"]["methods"][method]
        assert (temporal["pairs"], motion["pairs"]) == (9, 9)
        tepe, ego = temporal["criteria"]["all"], motion["criteria"]["gtfree:all"]
        assert cells == [
            *(f"{tepe[k]:.4f}" for k in ("tepe", "tepe_bad_0.5")),
            *(f"{ego[k]:.4f}" for k in ("mean_abs", "rms", "bad_0.5")),
        ], method
