"""``eval --confidence NAME=FILE``: the JSON's AUC is core's, and wrong inputs are one line.

A small synthetic frame: a GT PFM, an estimate with errors in a block, and an 8-bit confidence
PNG that rates the block low (with ties). The JSON's numbers must equal
:class:`~dispeval_ros.core.confidence.ConfidenceScorer`'s on the same arrays.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from dispeval_ros.cli.main import main
from dispeval_ros.core.confidence import ConfidenceScorer, parse_preset
from dispeval_ros.core.evaluator import Evaluator
from dispeval_ros.io.files import read_disparity, write_pfm

H, W = 24, 32


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    rng = np.random.default_rng(5)
    gt = (20.0 + 0.1 * np.arange(W, dtype=np.float32))[None, :].repeat(H, 0)
    est = gt + rng.normal(0, 0.3, gt.shape).astype(np.float32)
    est[4:12, 6:20] += rng.uniform(1.0, 6.0, (8, 14)).astype(np.float32)
    confidence = rng.integers(120, 255, gt.shape).astype(np.uint8)
    confidence[4:12, 6:20] = rng.integers(0, 140, (8, 14)).astype(np.uint8)
    paths = {"gt": tmp_path / "gt.pfm", "est": tmp_path / "est.pfm", "conf": tmp_path / "c.png"}
    write_pfm(paths["gt"], gt)
    write_pfm(paths["est"], est)
    cv2.imwrite(str(paths["conf"]), confidence)
    return paths


def run(files: dict[str, Path], *extra: str) -> list[str]:
    return ["eval", "--gt", str(files["gt"]), "--est", f"m={files['est']}",
            "--criteria", "all", *extra]  # fmt: skip


def failure(line: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(line) != 0
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    assert len(err.splitlines()) == 1, err
    return err


def test_json_auc_is_core(files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(run(files, "--confidence", f"m={files['conf']}", "--json")) == 0
    document = json.loads(capsys.readouterr().out)
    evaluator = Evaluator(criteria=("all",))
    confidence = cv2.imread(str(files["conf"]), cv2.IMREAD_UNCHANGED)
    assert confidence.dtype == np.uint8
    sums = ConfidenceScorer(evaluator, parse_preset("higher")).score(
        evaluator.reference(read_disparity(files["gt"])), read_disparity(files["est"]), confidence
    )
    expected = sums.summary()
    got = document["confidence"]["m"]["all"]
    for measure in ("bad_2", "d1", "mae"):
        for key in ("auc", "auc_opt", "ause", "ratio"):
            assert got[measure][key] == pytest.approx(expected["all"][measure][key], rel=1e-12)
    assert got["bad_2"]["ause"] > 0
    assert got["bad_2"]["auc"] < expected["all"]["bad_2"]["error"][-1]  # better than no ranking
    assert math.isclose(got["density"], 1.0)


def test_text_table(files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(run(files, "--confidence", f"m={files['conf']}", "--confidence-preset", "wls")) == 0
    out = capsys.readouterr().out
    for part in ("confidence of m:", "AUSE", "bad_2 [%]"):
        assert part in out


def test_unknown_preset(files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    line = run(files, "--confidence", f"m={files['conf']}", "--confidence-preset", "best")
    assert "unknown confidence preset 'best'" in failure(line, capsys)


def test_other_size(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((H - 2, W), np.uint8))
    err = failure(run(files, "--confidence", f"m={small}"), capsys)
    assert str(small) in err
    assert "the confidence is" in err


def test_nan_everywhere(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    nan = tmp_path / "nan.npy"
    np.save(nan, np.full((H, W), np.nan, np.float32))
    err = failure(run(files, "--confidence", f"m={nan}", "--confidence-preset", "zed"), capsys)
    assert str(nan) in err
    assert "no finite value" in err


def test_name_without_estimate(files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    err = failure(run(files, "--confidence", f"other={files['conf']}"), capsys)
    assert "no estimate is named 'other'" in err


def test_read_confidence_keeps_values_and_type(tmp_path: Path) -> None:
    from dispeval_ros.errors import InputError
    from dispeval_ros.io.files import read_confidence

    values = np.arange(H * W, dtype=np.uint16).reshape(H, W)
    cv2.imwrite(str(tmp_path / "c16.png"), values)
    got = read_confidence(tmp_path / "c16.png")
    assert got.dtype == np.uint16
    assert np.array_equal(got, values)  # not divided by 256 as a 16-bit disparity would be
    floats = (values / 7.0).astype(np.float32)
    cv2.imwrite(str(tmp_path / "c.tiff"), floats)
    assert np.array_equal(read_confidence(tmp_path / "c.tiff"), floats)
    np.save(tmp_path / "c8.npy", values.astype(np.uint8))
    assert read_confidence(tmp_path / "c8.npy").dtype == np.uint8
    with pytest.raises(InputError, match="unknown confidence file type"):
        read_confidence(tmp_path / "c.jpg")


def test_preset_per_method(files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    line = run(files, "--confidence", f"m={files['conf']}", "--json")
    assert main([*line, "--confidence-preset", "m=lower"]) == 0
    lower = json.loads(capsys.readouterr().out)["confidence"]["m"]["all"]["bad_2"]["auc"]
    assert main([*line, "--confidence-preset", "lower"]) == 0
    same = json.loads(capsys.readouterr().out)["confidence"]["m"]["all"]["bad_2"]["auc"]
    assert main(line) == 0
    higher = json.loads(capsys.readouterr().out)["confidence"]["m"]["all"]["bad_2"]["auc"]
    assert lower == same
    assert lower > higher  # the map rates the bad block low: read the other way, it ranks worse
    err = failure([*line, "--confidence-preset", "x=wls"], capsys)
    assert "names no --confidence method: x" in err


def test_plot(files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("matplotlib")
    png = tmp_path / "curves.png"
    assert (
        main(run(files, "--confidence", f"m={files['conf']}", "--confidence-plot", str(png))) == 0
    )
    assert f"sparsification curves: {png}" in capsys.readouterr().out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    err = failure(run(files, "--confidence-plot", str(png)), capsys)
    assert "need --confidence NAME=FILE" in err


def test_a_confidence_file_of_the_wrong_shape_names_the_confidence(tmp_path: Path) -> None:
    from dispeval_ros.errors import InputError
    from dispeval_ros.io.files import read_confidence

    path = tmp_path / "conf.npy"
    np.save(path, np.zeros((2, 3, 4)))
    with pytest.raises(InputError, match=r"confidence must be one H×W channel, found shape"):
        read_confidence(path)
