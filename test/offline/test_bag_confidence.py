"""``dispeval bag --confidence NAME=TOPIC``: confidence maps joined by stamp, pooled per unit.

The bag is make-bag's with ``--confidence`` (each OpenCV method's left-right confidence,
mono8). The stored curves must equal a plain sort-based numpy over every pixel of every frame
at once (``numpy_auc``, written from the definition), bad input must be a per-frame problem
or one line, and nothing already scored is lost.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from core.test_confidence import numpy_auc

from dispeval_ros.cli.main import main
from dispeval_ros.core.confidence import parse_preset
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.encoders import image_to_msg
from dispeval_ros.io.messages import disparity_from_msg, image_from_msg
from dispeval_ros.io.store import ResultsReader
from dispeval_ros.offline.make_bag import (
    CONFIDENCE_PRESET,
    GT_TOPIC,
    LEFT_INFO,
    RIGHT_INFO,
    confidence_topic,
    disparity_topic,
)
from dispeval_ros.stream.core import CoreConfig, EvaluationCore, FrameResult

METHODS = ("bm_fast", "sgbm")


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("confidence") / "drive"
    command = ["make-bag", str(path), "--frames", "4", "--width", "320", "--height", "120"]
    assert main([*command, "--no-lidar", "--confidence", "--json"]) == 0
    return path


def bag_command(bag: Path, out: Path, *extra: str) -> list[str]:
    command = ["bag", str(bag), "--gt", GT_TOPIC, "--camera-info", LEFT_INFO, RIGHT_INFO]
    for name in METHODS:
        command += ["--method", f"{name}={disparity_topic(name)}"]
        command += ["--confidence", f"{name}={confidence_topic(name)}"]
    return [*command, "--out", str(out), "--quiet", "--missing", "ignore", *extra]


def frames_of(bag: Path) -> dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """Per method, (GT, estimate, confidence) of every frame, decoded from the bag."""
    by_stamp: dict[str, dict[int, object]] = {}
    with BagSource(bag) as source:
        topics = [GT_TOPIC, *map(disparity_topic, METHODS), *map(confidence_topic, METHODS)]
        for topic, _, msg in source.messages(topics):
            by_stamp.setdefault(topic, {})[stamp_of(msg)] = msg
    found: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
    for name in METHODS:
        for stamp, gt_msg in sorted(by_stamp[GT_TOPIC].items()):
            gt = image_from_msg(gt_msg).array.astype(np.float64)
            est = disparity_from_msg(by_stamp[disparity_topic(name)][stamp])
            conf = image_from_msg(by_stamp[confidence_topic(name)][stamp]).array
            valid = (est.disparity >= est.est_range[0]) & (est.disparity <= est.est_range[1])
            found.setdefault(name, []).append((gt, np.where(valid, est.disparity, np.nan), conf))
    return found


def test_stored_curves_equal_numpy_over_all_pixels_at_once(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(bag_command(bag, out, "--criteria", "all")) == 0
    reader = ResultsReader.open(out)
    sequence = reader.sequences()[0] if hasattr(reader, "sequences") else "drive"
    stored = reader.confidence(sequence)
    assert stored is not None
    assert set(stored) == set(METHODS)
    preset = parse_preset(CONFIDENCE_PRESET)
    for name, frames in frames_of(bag).items():
        count, written, sums = stored[name]
        assert (count, written) == (len(frames), preset.text())
        gts, ests, confs = (np.concatenate([f[i].ravel() for f in frames]) for i in range(3))
        has_gt = np.isfinite(gts) & (gts > 0)  # the sky is inf: no ground truth
        assert sums.points[0] == has_gt.sum()
        scored = has_gt & np.isfinite(ests)  # ignore: points without an estimate: not scored
        error = np.abs(ests[scored] - gts[scored])
        rank = -confs[scored].astype(np.float64)  # higher is better: most confident first
        for threshold in (0.5, 2.0, 4.0):
            expected = numpy_auc(rank, (error > threshold).astype(np.float64)) * 100
            assert sums.curve("all", f"bad_{threshold:g}").auc == pytest.approx(expected, rel=1e-9)
        assert sums.curve("all", "mae").auc == pytest.approx(numpy_auc(rank, error), rel=1e-9)
        oracle = numpy_auc(error, error)  # ranked by the true error
        assert sums.curve("all", "mae").auc_opt == pytest.approx(oracle, rel=2e-2)
    pytest.importorskip("matplotlib")
    from dispeval_ros.report.confidence import write_confidence_figures

    (figure,) = write_confidence_figures(reader, tmp_path)
    assert figure.name == "confidence_drive.png"
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = json.loads((out / "summary.json").read_text())
    entry = summary["sequences"][0]["confidence"]["sgbm"]
    assert entry["frames"] == 4
    assert entry["preset"] == "higher"
    assert entry["criteria"]["all"]["bad_2"]["auc"] == pytest.approx(
        stored["sgbm"][2].curve("all", "bad_2").auc
    )


def test_resume_keeps_the_same_confidence_rows(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(bag_command(bag, out, "--criteria", "all", "--slice", "0.15")) == 0
    rows = (
        sqlite3.connect(out / "results.sqlite")
        .execute("SELECT method, frames FROM confidence_sums ORDER BY start, method")
        .fetchall()
    )
    assert sum(frames for _, frames in rows) == 2 * 4
    assert len(rows) > 2
    whole = tmp_path / "whole"
    assert main(bag_command(bag, whole, "--criteria", "all")) == 0
    sliced = ResultsReader.open(out).confidence("drive")
    single = ResultsReader.open(whole).confidence("drive")
    assert sliced is not None
    assert single is not None
    for name in METHODS:
        np.testing.assert_allclose(sliced[name][2].sums, single[name][2].sums, rtol=1e-12)


def core_with(bag: Path) -> tuple[EvaluationCore, list[tuple[str, int, object]]]:
    config = CoreConfig(
        methods={"sgbm": disparity_topic("sgbm")},
        gt_topic=GT_TOPIC,
        left_info_topic=LEFT_INFO,
        right_info_topic=RIGHT_INFO,
        confidences={"sgbm": confidence_topic("sgbm")},
        criteria=("all",),
    )
    with BagSource(bag) as source:
        messages = list(source.messages([t for t in config.topics if t in source.topics]))
    return EvaluationCore(config), messages


def scored(core: EvaluationCore, messages: list[tuple[str, int, Any]]) -> list[FrameResult]:
    sets = [s for topic, log, msg in messages for s in core.push(topic, msg, log)]
    return [core.score(s) for s in sets + core.flush()]


def test_bad_confidences_are_per_frame_problems_and_lose_no_score(bag: Path) -> None:
    core, messages = core_with(bag)
    gt_stamps = [log for topic, log, _ in messages if topic == GT_TOPIC]
    kept: list[tuple[str, int, object]] = []
    for topic, log, msg in messages:
        if topic == confidence_topic("sgbm") and log < gt_stamps[1]:  # frame 0: of another size
            small = image_to_msg(core_typestore(), np.zeros((10, 12), np.uint8), stamp_of(msg),
                                 "stereo_left", "mono8")  # fmt: skip
            kept.append((topic, log, small))
            continue
        if topic == confidence_topic("sgbm") and gt_stamps[1] <= log < gt_stamps[2]:
            continue  # frame 1: no confidence
        if topic == disparity_topic("sgbm") and gt_stamps[2] <= log < gt_stamps[3]:
            continue  # frame 2: a confidence without its estimate
        kept.append((topic, log, msg))
    results = sorted(scored(core, kept), key=lambda r: r.stamp)  # (joined as they complete)
    assert len(results) == 4
    texts = [text for r in results for _, text in r.problems]
    assert any("confidence is 12×10 but the ground truth is 320×120" in t for t in texts), texts
    assert any("no confidence map within" in t for t in texts), texts
    assert any("a confidence map but no estimate" in t for t in texts), texts
    assert [("sgbm" in r.scores, "sgbm" in r.confidence) for r in results] == [
        (True, False), (True, False), (False, False), (True, True),
    ]  # fmt: skip


def core_typestore() -> object:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def stamp_of(msg: object) -> int:
    stamp = msg.header.stamp  # type: ignore[attr-defined]
    return int(stamp.sec) * 10**9 + int(stamp.nanosec)


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        (["--confidence-preset", "brightest"], "unknown confidence preset 'brightest'"),
        (["--confidence", "nope=/stereo/nope/confidence"], "no method is named nope"),
        (
            ["--confidence-preset", "bm_smooth=zed"],
            "--confidence-preset: no method is named bm_smooth",
        ),
    ],
)
def test_wrong_options_are_one_line(
    bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], expected: str
) -> None:
    out = tmp_path / "out"
    assert main([*bag_command(bag, out), *extra]) == 2
    err = capsys.readouterr().err
    assert expected in err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not (out / "results.sqlite").exists()


def test_the_live_front_ends_refuse_confidences_in_one_line() -> None:
    from dispeval_ros.errors import ConfigurationError
    from dispeval_ros.ros.params import EVALUATOR_PARAMETERS, _core_config, core_config

    values = {param.name: param.default for param in EVALUATOR_PARAMETERS}
    values |= {"methods": ["sgbm:/stereo/sgbm/disparity"], "gt_topic": GT_TOPIC}
    values |= {"confidences": ["sgbm:/stereo/sgbm/confidence"]}
    values |= {"confidence_presets": ["sgbm:higher:0:100"]}
    parsed = _core_config(values)  # the parameters parse, the preset with its colons too
    assert parsed.confidence_presets == {"sgbm": "higher:0:100"}
    with pytest.raises(ConfigurationError, match="parameter confidences: confidence maps are"):
        core_config(values)


def test_live_refuses_confidences(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    command = ["live", "--gt", GT_TOPIC, "--method", f"sgbm={disparity_topic('sgbm')}"]
    command += ["--confidence", f"sgbm={confidence_topic('sgbm')}", "--out", str(tmp_path / "o")]
    assert main(command) == 2
    err = capsys.readouterr().err
    assert "--confidence: confidence maps are scored from recordings only" in err
