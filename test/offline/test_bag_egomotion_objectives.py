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

import pytest
from bag_support import NOISY_BIASED, noisy_biased_drive

from dispeval_ros.cli.main import main
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.summary import objective_table

FRAMES, WIDTH, HEIGHT = 5, 320, 96
METHODS = list(NOISY_BIASED)


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str]]:
    root = tmp_path_factory.mktemp("egoobjectives")
    return root, noisy_biased_drive(root, FRAMES, WIDTH, HEIGHT)


def run(drive: tuple[Path, list[str]], out: str, *measures: str) -> dict:
    root, args = drive
    command = [str(root / out) if a == str(root / "res") else a for a in args]
    assert main([*command, "--objective-measures", *measures]) == 0
    [sequence] = json.loads((root / out / "summary.json").read_text())["sequences"]
    return sequence


def test_adding_the_residual_makes_the_biased_method_a_first_group_member(
    drive: tuple[Path, list[str]],
) -> None:
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
    with ResultsStore.open(drive[0] / "both") as store:
        methods, names, matrix = objective_table(store, ["egomotion_mean_abs", "egomotion_bad_0.5"])
    assert names == both["objectives"][1:]
    for row, method in enumerate(methods):
        expected = [residual[method][c][key] for c in criteria for key in ("mean_abs", "bad_0.5")]
        assert list(matrix[row]) == expected


def test_residual_objectives_without_egomotion_are_one_line(
    drive: tuple[Path, list[str]], capsys: pytest.CaptureFixture[str]
) -> None:
    root, args = drive
    command = [str(root / "refused") if a == str(root / "res") else a for a in args]
    command.remove("--egomotion")
    assert main([*command, "--objective-measures", "egomotion_rms"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "ego-motion residual measures need --egomotion" in err
    assert not (root / "refused").exists()
