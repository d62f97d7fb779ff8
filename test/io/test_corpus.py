"""A corpus of malformed inputs, generated here, for every reader and command.

Each case must end the same way: exit status 2, exactly one line on stderr naming the problem,
no traceback, and nothing left behind (no results folder, no half-written bag). The cases are
made from a few valid files by damaging them in the ways real files get damaged.
"""

from __future__ import annotations

import io
import sqlite3
import zipfile
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest
from refusal_support import assert_refused as assert_one_line_error

from dispeval_ros.cli.main import main
from dispeval_ros.io.files import write_pfm

H, W = 24, 32


def pfm_bytes(array: np.ndarray) -> bytes:
    height, width = array.shape
    return f"Pf\n{width} {height}\n-1\n".encode() + np.flipud(array).astype("<f4").tobytes()


def png_bytes(array: np.ndarray) -> bytes:
    ok, encoded = cv2.imencode(".png", array)
    assert ok
    return encoded.tobytes()


def npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


GOOD = np.full((H, W), 12.0, np.float32)
GOOD_PFM = pfm_bytes(GOOD)
GOOD_PNG16 = png_bytes((GOOD * 256).astype(np.uint16))
GOOD_NPY = npy_bytes(GOOD)
GOOD_U8 = np.full((H, W), 9, np.uint8)
CALIB = (
    b"cam0=[100 0 16; 0 100 12; 0 0 1]\ncam1=[100 0 16; 0 100 12; 0 0 1]\ndoffs=0\nbaseline=100\n"
)

# name → (file name, content); every one is wrong as a disparity map
MAPS: dict[str, tuple[str, bytes]] = {
    "pfm-empty": ("d.pfm", b""),
    "pfm-garbage": ("d.pfm", b"\x00\xffnot a pfm at all" * 8),
    "pfm-truncated": ("d.pfm", GOOD_PFM[: len(GOOD_PFM) // 2]),
    "pfm-header-only": ("d.pfm", b"Pf\n32 24\n-1\n"),
    "pfm-bad-scale": ("d.pfm", b"Pf\n32 24\nabc\n" + bytes(W * H * 4)),
    "pfm-zero-size": ("d.pfm", b"Pf\n0 0\n-1\n"),
    "pfm-huge-dims": ("d.pfm", b"Pf\n100000 100000\n-1\n" + bytes(64)),
    "pfm-negative-dims": ("d.pfm", b"Pf\n-32 24\n-1\n" + bytes(W * H * 4)),
    "pfm-colour-as-grey": ("d.pfm", b"PF\n32 24\n-1\n" + bytes(W * H * 4)),
    "png-empty": ("d.png", b""),
    "png-garbage": ("d.png", b"\x89PNG\r\n\x1a\n" + b"\x00" * 40),
    "png-truncated": ("d.png", GOOD_PNG16[: len(GOOD_PNG16) // 2]),
    "png-colour": (
        "d.png",
        png_bytes(np.dstack([np.zeros((H, W), np.uint8)] * 2 + [np.full((H, W), 9, np.uint8)])),
    ),
    "png-is-pfm": ("d.png", GOOD_PFM),
    "npy-empty": ("d.npy", b""),
    "npy-garbage": ("d.npy", b"\x93NUMPY garbage"),
    "npy-truncated": ("d.npy", GOOD_NPY[: len(GOOD_NPY) // 2]),
    "npy-3d": ("d.npy", npy_bytes(np.zeros((2, H, W), np.float32))),
    "npy-strings": ("d.npy", npy_bytes(np.array(["a", "b"]))),
    "npz-empty-archive": ("d.npz", b"PK\x05\x06" + bytes(18)),
    "npz-garbage": ("d.npz", b"PK\x03\x04 not a zip"),
    "unknown-extension": ("d.xyz", GOOD_PFM),
    "no-extension": ("d", GOOD_PFM),
}


def write(folder: Path, name: str, content: bytes) -> Path:
    path = folder / name
    path.write_bytes(content)
    return path


def run(args: list[str]) -> int:
    """``dispeval ARGS`` as the shell runs it (argparse's own errors exit through SystemExit)."""
    try:
        return main(args)
    except SystemExit as exit_:
        return int(exit_.code or 0)


@pytest.fixture
def good(tmp_path: Path) -> Path:
    folder = tmp_path / "good"
    folder.mkdir()
    write_pfm(folder / "gt.pfm", GOOD)
    write_pfm(folder / "est.pfm", GOOD + 0.5)
    (folder / "calib.txt").write_bytes(CALIB)
    return folder


@pytest.mark.parametrize("case", sorted(MAPS))
@pytest.mark.parametrize("role", ["gt", "est", "gt-right", "mask"])
def test_eval_refuses_every_damaged_map_in_one_line(
    case: str, role: str, good: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    name, content = MAPS[case]
    bad = write(tmp_path, name, content)
    gt, est = good / "gt.pfm", good / "est.pfm"
    args = {
        "gt": ["--gt", str(bad), "--est", f"m={est}"],
        "est": ["--gt", str(gt), "--est", f"m={bad}"],
        "gt-right": ["--gt", str(gt), "--est", f"m={est}", "--gt-right", str(bad)],
        "mask": ["--gt", str(gt), "--est", f"m={est}", "--mask", f"nonocc={bad}"],
    }[role]
    code = run(["eval", *args])
    err = capfd.readouterr().err
    assert_one_line_error(code, err, bad.name)


CALIBS: dict[str, bytes] = {
    "empty": b"",
    "garbage": b"\x00\x01\x02 binary",
    "no-baseline": b"cam0=[100 0 16; 0 100 12; 0 0 1]\ndoffs=0\n",
    "zero-baseline": CALIB.replace(b"baseline=100", b"baseline=0"),
    "negative-focal": CALIB.replace(b"cam0=[100", b"cam0=[-100"),
    "nan-baseline": CALIB.replace(b"baseline=100", b"baseline=nan"),
    "text-matrix": b"cam0=[a b c; d e f; g h i]\nbaseline=100\n",
    "kitti-short-P": b"P_rect_02: 1 2 3\nP_rect_03: 1 2 3\n",
}


@pytest.mark.parametrize("case", sorted(CALIBS))
def test_eval_refuses_every_damaged_calibration(
    case: str, good: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    calib = write(tmp_path, "calib.txt", CALIBS[case])
    code = run(
        [
            "eval",
            "--gt",
            str(good / "gt.pfm"),
            "--est",
            f"m={good / 'est.pfm'}",
            "--calib",
            str(calib),
        ]
    )
    assert_one_line_error(code, capfd.readouterr().err, "calib")


OPTIONS: dict[str, list[str]] = {
    "missing-gt-file": ["--gt", "NOPE.pfm"],
    "directory-as-gt": ["--gt", "{tmp}"],
    "est-without-name-twice": ["--est", "{est}"],
    "delta-zero": ["--delta", "0"],
    "delta-nan": ["--delta", "nan"],
    "mu-negative": ["--mu", "-1"],
    "unknown-criterion": ["--criteria", "nope"],
    "unknown-measure": ["--measures", "nope"],
    "unknown-policy": ["--missing", "nope"],
    "bad-depth-ranges": ["--depth-ranges", "10-5"],
    "focal-without-baseline": ["--focal", "100"],
    "roi-labels-without-roi": ["--roi-labels", "1=road"],
    "unknown-protocol": ["--protocol", "nope"],
}


@pytest.mark.parametrize("case", sorted(OPTIONS))
def test_eval_refuses_every_bad_option_in_one_line(
    case: str, good: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    extra = [a.format(tmp=tmp_path, est=good / "est.pfm") for a in OPTIONS[case]]
    base = ["--gt", str(good / "gt.pfm"), "--est", f"m={good / 'est.pfm'}"]
    if case == "missing-gt-file" or case == "directory-as-gt":
        base = ["--est", f"m={good / 'est.pfm'}"]
    if case == "est-without-name-twice":
        base = ["--gt", str(good / "gt.pfm"), "--est", str(good / "est.pfm")]
    code = run(["eval", *base, *extra])
    assert_one_line_error(code, capfd.readouterr().err)


def results_variants(folder: Path) -> dict[str, Callable[[], Path]]:
    """Damaged results folders, made on demand."""

    def empty_folder() -> Path:
        (folder / "empty").mkdir()
        return folder / "empty"

    def garbage_database() -> Path:
        (folder / "garbage").mkdir()
        (folder / "garbage" / "results.sqlite").write_bytes(b"not sqlite" * 50)
        return folder / "garbage"

    def foreign_database() -> Path:
        (folder / "foreign").mkdir()
        with sqlite3.connect(folder / "foreign" / "results.sqlite") as connection:
            connection.execute("CREATE TABLE notes (text TEXT)")
        return folder / "foreign"

    def truncated_database() -> Path:
        (folder / "truncated").mkdir()
        with sqlite3.connect(folder / "truncated" / "results.sqlite") as connection:
            connection.execute("CREATE TABLE notes (text TEXT)")
            connection.executemany("INSERT INTO notes VALUES (?)", [("x" * 500,)] * 200)
        data = (folder / "truncated" / "results.sqlite").read_bytes()
        (folder / "truncated" / "results.sqlite").write_bytes(data[: len(data) // 3])
        return folder / "truncated"

    return {
        "missing": lambda: folder / "missing",
        "empty-folder": empty_folder,
        "garbage-database": garbage_database,
        "foreign-database": foreign_database,
        "truncated-database": truncated_database,
    }


@pytest.mark.parametrize("command", ["report", "models"])
@pytest.mark.parametrize(
    "case",
    ["missing", "empty-folder", "garbage-database", "foreign-database", "truncated-database"],
)
def test_results_readers_refuse_damaged_results(
    command: str, case: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    results = results_variants(tmp_path)[case]()
    code = run([command, str(results)])
    assert_one_line_error(code, capfd.readouterr().err)
    assert not (results / "report.html").exists()


CSVS: dict[str, bytes] = {
    "empty": b"",
    "header-only": b"method,a,b\n",
    "no-method-column": b"name,a\nx,1\n",
    "not-a-number": b"method,a\nx,fast\n",
    "ragged": b"method,a,b\nx,1\n",
    "binary": bytes(range(256)),
    "no-objective": b"method\nx\ny\n",
}


@pytest.mark.parametrize("case", sorted(CSVS))
def test_models_refuses_every_bad_table(
    case: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    table = write(tmp_path, "scores.csv", CSVS[case])
    code = run(["models", str(table)])
    assert_one_line_error(code, capfd.readouterr().err, "scores.csv")


@pytest.mark.parametrize(
    "args",
    [
        ["--thumbnails", "-1"],
        ["--bag", "NOPE"],
    ],
    ids=["negative-thumbnails", "missing-bag"],
)
def test_report_refuses_bad_options_and_writes_nothing(
    args: list[str], tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    from dispeval_ros.core import Evaluator
    from dispeval_ros.io.store import FrameScores, ResultsStore

    evaluator = Evaluator(("all",), ("bmp", "mae", "density"))
    with ResultsStore.create(tmp_path / "R", {"criteria": ["all"]}) as store:
        store.add_unit("s", "u", [FrameScores("s", 1, "m", evaluator.score(GOOD, GOOD + 1))])
    code = run(
        ["report", str(tmp_path / "R"), *[a.replace("NOPE", str(tmp_path / "x")) for a in args]]
    )
    assert_one_line_error(code, capfd.readouterr().err)
    assert not (tmp_path / "R" / "report.html").exists()


BAGS: dict[str, bytes] = {
    "empty-mcap": b"",
    "garbage-mcap": b"\x89MCAP0\r\n" + b"\xff" * 64,
    "text-as-mcap": b"hello world\n" * 10,
}


@pytest.mark.parametrize("case", sorted(BAGS))
@pytest.mark.parametrize("command", ["bag", "play", "report-bag"])
def test_bag_readers_refuse_damaged_bags(
    case: str, command: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    bag = write(tmp_path, "drive.mcap", BAGS[case])
    out = tmp_path / "R"
    if command == "bag":
        args = ["bag", str(bag), "--gt", "/gt", "--method", "m=/m", "--out", str(out)]
    elif command == "play":
        args = ["play", str(bag), "--domain-id", "7"]
    else:
        args = ["make-bag", str(out), "--scene", str(bag)]
    code = run(args)
    assert_one_line_error(code, capfd.readouterr().err)
    assert not out.exists()


def test_merge_refuses_what_is_not_results(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "a").mkdir()
    code = run(["merge", str(tmp_path / "out"), str(tmp_path / "a"), str(tmp_path / "b")])
    assert_one_line_error(code, capfd.readouterr().err)
    assert not (tmp_path / "out").exists()


def test_npz_with_two_arrays_names_them(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "d.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("a.npy", npy_bytes(GOOD))
        archive.writestr("b.npy", npy_bytes(GOOD))
    code = run(["eval", "--gt", str(path), "--est", f"m={path}"])
    assert_one_line_error(code, capfd.readouterr().err, "'a'", "'b'")
