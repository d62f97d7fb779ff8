"""The ``dispeval`` command line: outputs, JSON shape, and one-line errors with status 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from sample_feed import sample_bag, sample_config, topic_args

from dispeval_ros.cli.main import main
from dispeval_ros.io import write_disparity_png16, write_pfm


def run_cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.fixture
def frame_files(tmp_path: Path) -> dict[str, Path]:
    """A small GT (PFM) and two estimates (KITTI PNG and NPY) with known errors."""
    gt = np.tile(np.linspace(10, 40, 64, dtype=np.float32), (48, 1))
    gt[20:30, 20:40] = 60.0  # a near box: boundaries and occlusion
    gt[0, :5] = np.inf  # unknown GT
    good = gt.copy()
    good[~np.isfinite(good)] = 10.0
    good += 0.25
    bad = good.copy()
    bad[:, ::4] += 3.0
    bad[5, 5:9] = 0.0  # holes
    paths = {"gt": tmp_path / "gt.pfm", "good": tmp_path / "good.png", "bad": tmp_path / "bad.npy"}
    write_pfm(paths["gt"], gt)
    write_disparity_png16(paths["good"], good)
    np.save(paths["bad"], bad)
    return paths


def test_eval_json_shape_and_values(
    capsys: pytest.CaptureFixture[str], frame_files: dict[str, Path]
) -> None:
    code, out, _ = run_cli(
        capsys,
        "eval",
        "--gt",
        str(frame_files["gt"]),
        "--est",
        f"good={frame_files['good']}",
        "--est",
        str(frame_files["bad"]),
        "--focal",
        "700",
        "--baseline",
        "0.5",
        "--json",
    )
    assert code == 0
    document = json.loads(out)
    assert [f["method"] for f in document["frames"]] == ["good", "bad"]
    good = document["frames"][0]["criteria"]
    assert set(good) == {"all", "occluded", "boundary", "interior", "near", "mid", "far"}
    assert good["all"]["n"] == 48 * 64 - 5
    assert good["all"]["mae"] == pytest.approx(0.25, abs=1 / 512)
    assert good["all"]["bmp"] == 0.0
    bad = document["frames"][1]["criteria"]
    assert bad["all"]["bmp"] > 20
    assert document["models"]["groups"] == {"good": 1, "bad": 2}
    assert document["models"]["astar"] == ["good"]
    assert document["sze_relative"] is False


def test_eval_human_output_lists_every_criterion(
    capsys: pytest.CaptureFixture[str], frame_files: dict[str, Path]
) -> None:
    code, out, _ = run_cli(
        capsys, "eval", "--gt", str(frame_files["gt"]), "--est", str(frame_files["good"])
    )
    assert code == 0
    for criterion in ("all", "occluded", "boundary", "interior", "near", "mid", "far"):
        assert f"criterion: {criterion}" in out
    assert "SZE is relative" in out


def test_eval_scene_with_official_masks(
    capsys: pytest.CaptureFixture[str], shared_data: Path
) -> None:
    teddy = shared_data / "middlebury-2001-2003" / "teddy"
    code, out, _ = run_cli(
        capsys,
        "eval",
        "--scene",
        str(teddy),
        "--est",
        f"right={teddy / 'groundtruth_right.png'}",
        "--est-scale",
        "4",
        "--criteria",
        "visibility",
        "legacy",
        "--json",
    )
    assert code == 0
    document = json.loads(out)
    assert document["partition"] == {
        "occluded": 17693,
        "boundary": 40517,
        "interior": 107134,
        "nonocc": 147651,
        "all": 165344,
        "disc": 40517,
    }
    assert set(document["overlapping"]) == {"nonocc", "all", "disc"}


WORKED = "method,o1,o2\na,1,4\nb,2,2\nc,3,3\nd,4,1\n"


def test_models_worked_check(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    csv_file = tmp_path / "scores.csv"
    csv_file.write_text(WORKED)
    code, out, _ = run_cli(capsys, "models", str(csv_file), "--json")
    assert code == 0
    document = json.loads(out)
    assert set(document) == {
        "astar",
        "groups",
        "reduction",
        "reduced",
        "middlebury",
        "interpretation",
    }
    assert document["astar"] == ["a", "b", "d"]
    assert document["groups"] == {"a": 1, "b": 1, "c": 2, "d": 1}
    assert document["reduction"]["b"] == {"u1": 4.0, "u2": pytest.approx(2 / 3)}
    assert document["reduced"] == ["b"]
    code, out, _ = run_cli(capsys, "models", str(csv_file))
    assert code == 0
    assert "A* group" in out
    assert "b" in out


def test_models_consistency(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    csv_file = tmp_path / "scores.csv"
    csv_file.write_text("method,all/sze,all/bmp\na,1,3\nb,2,2\nc,3,1\n")
    code, out, _ = run_cli(capsys, "models", str(csv_file), "--consistency", "sze", "bmp", "--json")
    assert code == 0
    # sze: a<b<c (groups 1,2,3); bmp: c<b<a: every pair's relation is reversed
    assert json.loads(out)["consistency"]["share"] == 0.0


@pytest.mark.parametrize(
    ("setup", "expected"),
    [
        (
            lambda d: ["eval", "--gt", str(d / "missing.pfm"), "--est", str(d / "good.png")],
            "missing.pfm",
        ),
        (lambda d: ["eval", "--gt", str(d / "gt.pfm"), "--est", str(d / "small.npy")], "small.npy"),
        (
            lambda d: ["eval", "--gt", str(d / "invalid.npy"), "--est", str(d / "good.png")],
            "no valid point",
        ),
        (
            lambda d: ["eval", "--gt", str(d / "gt.pfm"), "--est", str(d / "complex.npy")],
            "complex.npy",
        ),
        (
            lambda d: [
                "eval",
                "--gt",
                str(d / "gt.pfm"),
                "--est",
                str(d / "good.png"),
                "--calib",
                str(d / "nocalib.txt"),
            ],
            "nocalib.txt",
        ),
        (lambda d: ["eval", "--scene", str(d), "--est", str(d / "good.png")], str(Path("tmp"))),
        (
            lambda d: [
                "eval",
                "--gt",
                str(d / "gt.pfm"),
                "--est",
                str(d / "good.png"),
                "--measures",
                "nope",
            ],
            "nope",
        ),
        (
            lambda d: [
                "eval",
                "--gt",
                str(d / "gt.pfm"),
                "--est",
                str(d / "good.png"),
                "--criteria",
                "nope",
            ],
            "nope",
        ),
        (lambda d: ["models", str(d / "bad.csv")], "bad.csv"),
    ],
    ids=[
        "unreadable",
        "size-mismatch",
        "all-invalid-gt",
        "wrong-dtype",
        "missing-calibration",
        "unknown-layout",
        "unknown-measure",
        "unknown-criterion",
        "bad-csv",
    ],
)
def test_bad_input_is_one_line_with_status_2(
    capsys: pytest.CaptureFixture[str],
    frame_files: dict[str, Path],
    setup,
    expected: str,  # type: ignore[no-untyped-def]
) -> None:
    folder = frame_files["gt"].parent
    np.save(folder / "small.npy", np.ones((10, 10), np.float32))
    np.save(folder / "invalid.npy", np.zeros((48, 64), np.float32))
    np.save(folder / "complex.npy", np.ones((48, 64), np.complex64))
    (folder / "bad.csv").write_text("method,o1\na,x\n")
    code, _out, err = run_cli(capsys, *setup(folder))
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert expected in lines[0]
    assert "Traceback" not in err


def test_error_in_a_real_process_has_no_traceback(tmp_path: Path) -> None:
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "dispeval_ros",
            "eval",
            "--gt",
            str(tmp_path / "nope.pfm"),
            "--est",
            "x.pfm",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1
    assert "nope.pfm" in result.stderr
    assert "Traceback" not in result.stderr


def test_demo_runs_and_ranks_methods(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli(
        capsys, "demo", "--single-scene", "--json", "--width", "320", "--height", "200"
    )
    assert code == 0
    document = json.loads(out)
    methods = [frame["method"] for frame in document["frames"]]
    assert len(methods) >= 3
    assert set(document["models"]["groups"]) == set(methods)
    assert 1 in document["models"]["groups"].values()
    assert document["models"]["interpretation"]


@pytest.fixture(scope="module")
def bag_results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``dispeval bag`` on the sample bag."""
    bag = sample_bag()
    out = tmp_path_factory.mktemp("models") / "results"
    args = ["bag", str(bag), *topic_args(sample_config(bag)), "--out", str(out), "--quiet"]
    assert main(args) == 0
    return out


def test_models_of_results_equal_their_summary_and_export_round_trips(
    bag_results: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    summary = json.loads((bag_results / "summary.json").read_text())
    (sequence,) = summary["sequences"]
    exported = tmp_path / "objectives.csv"
    for source in (bag_results, bag_results / "results.sqlite", bag_results / "frames.csv"):
        capsys.readouterr()
        assert main(["models", str(source), "--json", "--export", str(exported)]) == 0
        result = json.loads(capsys.readouterr().out)
        assert result["groups"] == sequence["models"]["groups"]
        assert result["reduced"] == sequence["models"]["reduced"]
        header = exported.read_text().splitlines()[0].split(",")
        assert header == ["method", *sequence["objectives"]]
    assert main(["models", str(exported), "--json"]) == 0  # the export reads back
    assert json.loads(capsys.readouterr().out)["groups"] == sequence["models"]["groups"]
    assert main(["models", str(bag_results), "--objectives", "frame", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["groups"]


def test_models_of_results_bad_input_is_one_line(
    bag_results: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    alone = tmp_path / "frames.csv"
    alone.write_bytes((bag_results / "frames.csv").read_bytes())
    assert main(["models", str(alone)]) == 2
    assert "no results.sqlite is beside it" in capsys.readouterr().err
    assert main(["models", str(bag_results), "--objective-measures", "a99"]) == 2
    assert "a99 were not computed" in capsys.readouterr().err
    assert main(["models", str(tmp_path / "missing")]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_tables_fit_the_terminal_and_carry_units(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("COLUMNS", "100")
    gt = tmp_path / "gt.pfm"
    write_pfm(gt, np.full((30, 40), 20.0, np.float32))
    est = tmp_path / "est.pfm"
    write_pfm(est, np.full((30, 40), 21.5, np.float32))
    args = ["eval", "--gt", str(gt), "--est", f"a={est}", "--est", f"b={gt}"]
    assert main([*args, "--focal", "500", "--baseline", "0.1"]) == 0
    out = capsys.readouterr().out
    tables = [line for line in out.splitlines() if line.startswith(("method", "---", "a ", "b "))]
    assert tables
    assert max(len(line) for line in tables) <= 100
    for header in ("sze [m]", "sze_mean [m]", "bmp [%]", "mae [px]", "density [share]"):
        assert header in out, header
    assert main([*args, "--json"]) == 0  # no camera: SZE is relative, and counts are integers
    document = json.loads(capsys.readouterr().out)
    values = document["frames"][0]["criteria"]["all"]
    assert values["n"] == 1200
    assert isinstance(values["n"], int)
    assert isinstance(values["bmp_count"], int)
    assert main(args) == 0
    assert "sze [relative (no camera)]" in capsys.readouterr().out


def test_sequence_summaries_show_sze_per_point(
    bag_results: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    summary = json.loads((bag_results / "summary.json").read_text())
    (sequence,) = summary["sequences"]
    scores = sequence["scores"]["sgbm"]["all"]
    assert scores["sze_mean"] == pytest.approx(scores["sze"] / scores["n"], rel=1e-12)
    assert isinstance(scores["n"], int)


def test_eval_with_only_legacy_criteria_says_why_there_is_no_model(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    gt = tmp_path / "gt.pfm"
    write_pfm(gt, np.full((30, 40), 20.0, np.float32))
    est = tmp_path / "est.pfm"
    write_pfm(est, np.full((30, 40), 21.5, np.float32))
    args = [
        "eval",
        "--gt",
        str(gt),
        "--est",
        f"a={est}",
        "--est",
        f"b={gt}",
        "--criteria",
        "legacy",
    ]
    assert main(args) == 0
    assert "no A* Groups: the legacy criteria overlap" in capsys.readouterr().out
    assert main([*args, "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["models"] is None
    assert "overlap" in document["models_note"]
