"""The ego-motion residual as an objective (``--objective-measures sze egomotion_mean_abs …``).

Hand-worked expectation on a synthetic drive with its exact /tf: method ``noisy`` is the GT
with 0.5 px of Gaussian noise, ``biased`` the GT plus a constant 1.5 px. On SZE alone
``noisy`` is better (its errors are smaller), so A* Groups puts it first and ``biased`` second.
The residual is temporal noise: the constant bias is removed by the offset fit and the GT
fits its exact motion (few residuals above 0.5 px), while ``noisy``'s residual has 0.5·√2 px
of noise (about half above 0.5 px), so adding ``egomotion_mean_abs`` and ``egomotion_bad_0.5``
makes the two incomparable: one group of both. The objectives are on ``gtfree:`` criteria and
equal summary.json's ``egomotion`` entry.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dispeval_ros.cli.main import main
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import (
    GT_TOPIC,
    LEFT_IMAGE,
    LEFT_INFO,
    RIGHT_IMAGE,
    RIGHT_INFO,
    disparity_topic,
    estimates_from,
    synthetic_frames,
    write_bag,
)
from dispeval_ros.summary import objective_table
from dispeval_ros.testbed.methods import default_methods

FRAMES, WIDTH, HEIGHT = 5, 320, 96
METHODS = {"noisy": (0.5, 0.0), "biased": (0.0, 1.5)}
"""Per method: px of Gaussian noise and a constant px offset added to the GT."""


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("egoobjectives")
    frames = list(synthetic_frames(FRAMES, WIDTH, HEIGHT, 10.0, seed=4))
    rng = np.random.default_rng(7)
    sources = []
    for name, (sigma, bias) in METHODS.items():
        (root / name).mkdir()
        for index, frame in enumerate(frames):
            assert frame.gt is not None
            gt = frame.gt.astype(np.float32)
            estimate = gt + bias + rng.normal(0, sigma, gt.shape).astype(np.float32)
            estimate = np.where(np.isfinite(gt), np.clip(estimate, 0.5, None), np.inf)
            np.save(root / name / f"{index:06d}.npy", estimate.astype(np.float32))
        sources.append(estimates_from(name, root / name))
    write_bag(
        root / "drive", iter(frames), storage="rosbag2-sqlite3",
        methods=default_methods(WIDTH)[:1], estimates=sources,
    )  # fmt: skip
    return root


def run(root: Path, out: str, *measures: str) -> dict:
    methods = [item for name in METHODS for item in ("--method", f"{name}={disparity_topic(name)}")]
    assert main([
        "bag", str(root / "drive"), "--gt", GT_TOPIC, *methods, "--camera-info", LEFT_INFO,
        RIGHT_INFO, "--left-image", LEFT_IMAGE, "--right-image", RIGHT_IMAGE, "--egomotion",
        "--criteria", "all", "--out", str(root / out), "--quiet", "--objective-measures",
        *measures,
    ]) == 0  # fmt: skip
    [sequence] = json.loads((root / out / "summary.json").read_text())["sequences"]
    return sequence


def test_adding_the_residual_makes_the_biased_method_a_first_group_member(drive: Path) -> None:
    accuracy = run(drive, "sze", "sze")
    assert accuracy["objectives"] == ["all/sze @drive"]
    assert accuracy["models"]["groups"] == {"noisy": 1, "biased": 2}
    both = run(drive, "both", "sze", "egomotion_mean_abs", "egomotion_bad_0.5")
    residual = {m: both["egomotion"][m]["criteria"] for m in METHODS}
    criteria = list(residual["noisy"])
    assert criteria[0] == "gtfree:all"
    assert all(c.startswith("gtfree:") for c in criteria)
    assert both["objectives"] == ["all/sze @drive"] + [
        f"{c}/{m} @drive" for c in criteria for m in ("egomotion_mean_abs", "egomotion_bad_0.5")
    ]
    assert both["models"]["groups"] == {"noisy": 1, "biased": 1}
    biased, noisy = residual["biased"]["gtfree:all"], residual["noisy"]["gtfree:all"]
    assert biased["bad_0.5"] < 10 < 40 < noisy["bad_0.5"]  # (0.5·√2 px of noise: ≈ 48 %)
    assert biased["mean_abs"] < noisy["mean_abs"]
    assert both["scores"]["noisy"]["all"]["sze"] < both["scores"]["biased"]["all"]["sze"]
    with ResultsStore.open(drive / "both") as store:
        methods, names, matrix = objective_table(store, ["egomotion_mean_abs", "egomotion_bad_0.5"])
    assert names == both["objectives"][1:]
    for row, method in enumerate(methods):
        expected = [residual[method][c][key] for c in criteria for key in ("mean_abs", "bad_0.5")]
        assert list(matrix[row]) == expected


def test_residual_objectives_without_egomotion_are_one_line(
    drive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = [
        "bag", str(drive / "drive"), "--gt", GT_TOPIC, "--method",
        f"noisy={disparity_topic('noisy')}", "--camera-info", LEFT_INFO, RIGHT_INFO,
        "--out", str(drive / "refused"), "--quiet", "--objective-measures", "egomotion_mean_abs",
    ]  # fmt: skip
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "ego-motion residual measures need --egomotion" in err
