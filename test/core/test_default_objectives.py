"""The default objectives follow the measures asked for (``--measures`` alone never fails).

SZE and BMPRE where scored, else the ground-truth measures scored but density, vpe without
ground truth; a named ``--objective-measures`` outside the measures scored is still refused.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from sample_feed import sample_bag, sample_config, topic_args

from dispeval_ros.cli.main import main
from dispeval_ros.core.objectives import default_objective_measures
from dispeval_ros.io import write_pfm


@pytest.mark.parametrize(
    ("scored", "expected"),
    [
        (["bmp", "sze", "mae", "bmpre", "density"], ["sze", "bmpre"]),
        (["bmp", "mae", "density"], ["bmp", "mae"]),
        (["mae", "bmpre", "vpe"], ["bmpre"]),
        (["bmp", "vpe", "lrc", "density"], ["bmp"]),
        (["vpe", "lrc", "density"], ["vpe"]),
        (["density"], ["density"]),
    ],
)
def test_rule(scored: list[str], expected: list[str]) -> None:
    assert default_objective_measures(scored) == expected


def test_eval_with_narrowed_measures_ranks_on_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    gt = np.tile(np.linspace(10, 40, 32, dtype=np.float32), (24, 1))
    files = {"gt": gt, "a": gt + 0.5, "b": gt + 2.0}  # b: worse on bmp and on mae
    for name, value in files.items():
        write_pfm(tmp_path / f"{name}.pfm", value)
    argv = ["eval", "--gt", str(tmp_path / "gt.pfm"), "--criteria", "all", "--json"]
    argv += ["--est", f"a={tmp_path / 'a.pfm'}", "--est", f"b={tmp_path / 'b.pfm'}"]
    assert main([*argv, "--measures", "bmp", "mae"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["objectives"] == ["all/bmp", "all/mae"]
    assert document["models"]["groups"] == {"a": 1, "b": 2}


@pytest.fixture(scope="module")
def narrowed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``dispeval bag`` of the sample bag with ``--measures bmp mae`` and nothing else."""
    bag = sample_bag()
    out = tmp_path_factory.mktemp("narrowed") / "results"
    argv = ["bag", str(bag), *topic_args(sample_config(bag)), "--out", str(out), "--quiet"]
    assert main([*argv, "--measures", "bmp", "mae"]) == 0
    return out


def test_bag_with_narrowed_measures_ranks_on_them(
    narrowed: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    summary = json.loads((narrowed / "summary.json").read_text())
    assert summary["objective_measures"] == ["bmp", "mae"]
    objectives = summary["overall"]["objectives"] or summary["sequences"][0]["objectives"]
    assert objectives
    assert {name.split(" @")[0].split("/")[1] for name in objectives} == {"bmp", "mae"}
    capsys.readouterr()
    assert main(["models", str(narrowed), "--json"]) == 0  # the stored measures, likewise
    assert (
        json.loads(capsys.readouterr().out)["groups"] == summary["sequences"][0]["models"]["groups"]
    )


def test_named_objective_outside_the_measures_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = sample_bag()
    out = tmp_path / "results"
    argv = ["bag", str(bag), *topic_args(sample_config(bag)), "--out", str(out), "--quiet"]
    assert main([*argv, "--measures", "bmp", "mae", "--objective-measures", "bmpre"]) == 2
    err = capsys.readouterr().err
    assert "--objective-measures bmpre: not among the measures scored (bmp, mae" in err
    assert len(err.strip().splitlines()) == 1
    assert not out.exists()
