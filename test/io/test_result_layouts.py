"""Each protocol's result layouts are defined once and read by the lookup, its errors and README.

Built from the shared KITTI and MiddEval3 data in tmp folders: the README's KITTI layout
(``disp_0/NNNNNN_10.png``) is found, a folder holding a PFM beside the PNG scores the PNG (it
used to pick the PFM and then refuse it), two files that both fit are refused by name, and a
missing result names every place looked at (not cut off) and the encoding the tool reads.
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from dispeval_ros.cli.main import main
from dispeval_ros.core.protocols import PROTOCOLS, get_protocol
from dispeval_ros.io import read_disparity, write_pfm
from dispeval_ros.io.benchmarks import discover, estimate_candidates

README = Path(__file__).resolve().parents[2] / "README.md"
VELODYNE = "kitti-lidar/kitti2015-with-velodyne"
FRAMES = ("000010", "000043")


def _words(text: str) -> str:
    return " ".join(text.split())


def test_readme_lists_every_protocols_layouts_as_defined() -> None:
    text = README.read_text(encoding="utf-8")
    block = re.search(r"<!-- result-layouts -->\n(.*?)<!-- /result-layouts -->", text, re.S)
    assert block, "README.md has no result-layouts block"
    expected = " ".join(f"- `{p.name}`: {p.results.describe()}" for p in PROTOCOLS.values())
    assert _words(block.group(1)) == _words(expected)


@pytest.fixture
def kitti_tree(shared_data: Path, tmp_path: Path) -> Path:
    """A KITTI 2015 ``training/`` tree with frames named as the official release names them."""
    source = shared_data / VELODYNE / "gt"
    for folder in ("disp_occ_0", "obj_map"):
        (tmp_path / "training" / folder).mkdir(parents=True)
        for frame in FRAMES:
            shutil.copy(
                source / folder / f"{frame}.png", tmp_path / "training" / folder / f"{frame}_10.png"
            )
    return tmp_path / "training"


def _results(shared_data: Path, folder: Path, layout: str, pfm_beside: bool = False) -> Path:
    """The shared PSMNet predictions laid out as ``layout`` ({frame}: NNNNNN_10)."""
    for frame in FRAMES:
        target = folder / layout.format(frame=f"{frame}_10")
        target.parent.mkdir(parents=True, exist_ok=True)
        prediction = shared_data / VELODYNE / "prediction" / f"{frame}.png"
        shutil.copy(prediction, target)
        if pfm_beside:
            write_pfm(target.with_suffix(".pfm"), read_disparity(prediction))
            write_pfm(folder / f"{frame}_10.pfm", read_disparity(prediction))
    return folder


def _summary(capsys: pytest.CaptureFixture[str], tree: Path, results: Path) -> object:
    argv = ["eval", "--protocol", "kitti2015", "--scene", str(tree), "--est", f"m={results}"]
    code = main([*argv, "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)["methods"]["m"]


def test_the_readme_kitti_layout_is_found_and_a_pfm_beside_it_is_not_read(
    shared_data: Path, kitti_tree: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plain = _results(shared_data, tmp_path / "plain", "disp_0/{frame}.png")
    mixed = _results(shared_data, tmp_path / "mixed", "disp_0/{frame}.png", pfm_beside=True)
    expected = _summary(capsys, kitti_tree, plain)
    assert _summary(capsys, kitti_tree, mixed) == expected
    for layout in get_protocol("kitti2015").results.folder:  # every listed layout is read
        other = _results(shared_data, tmp_path / layout.replace("/", "_"), layout)
        assert _summary(capsys, kitti_tree, other) == expected


def _one_line_error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "Traceback" not in err
    return err


def test_a_missing_result_names_every_place_and_the_encoding(
    shared_data: Path, kitti_tree: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    results = tmp_path / "results"
    (results / "disp_0").mkdir(parents=True)
    write_pfm(
        results / "disp_0" / "000010_10.pfm",
        read_disparity(kitti_tree / "disp_occ_0/000010_10.png"),
    )
    protocol = get_protocol("kitti2015")
    frame = discover(protocol, kitti_tree)[0]
    err = _one_line_error(
        capsys,
        ["eval", "--protocol", "kitti2015", "--scene", str(kitti_tree), "--est", f"m={results}"],
    )
    for candidate in estimate_candidates(protocol, frame, "m", results):
        assert str(candidate) in err
    assert "..." not in err
    assert protocol.results.encoding_text() in err
    assert f"found {results / 'disp_0' / '000010_10.pfm'}, not read" in err


def test_two_results_that_both_fit_are_refused_naming_both(
    shared_data: Path, kitti_tree: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    results = _results(shared_data, tmp_path / "results", "disp_0/{frame}.png")
    _results(shared_data, results, "{frame}.png")
    err = _one_line_error(
        capsys,
        ["eval", "--protocol", "kitti2015", "--scene", str(kitti_tree), "--est", f"m={results}"],
    )
    assert str(results / "disp_0" / "000010_10.png") in err
    assert str(results / "000010_10.png") in err


def test_kitti_results_are_never_looked_for_in_the_gt_tree(
    kitti_tree: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    err = _one_line_error(
        capsys, ["eval", "--protocol", "kitti2015", "--scene", str(kitti_tree), "--est", "m"]
    )
    assert "give --est m=RESULTS" in err
    assert "RESULTS/disp_0/<frame>.png" in err


def test_middeval3_results_folder_layouts(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tree = tmp_path / "trainingQ" / "Teddy"
    tree.mkdir(parents=True)
    for file in (shared_data / "middeval3-training-Q" / "Teddy").iterdir():
        (tree / file.name).symlink_to(file)
    gt = read_disparity(tree / "disp0GT.pfm")
    results = tmp_path / "results"
    (results / "Teddy").mkdir(parents=True)
    write_pfm(results / "Teddy.pfm", gt)
    argv = ["eval", "--protocol", "middeval3", "--scene", str(tree.parent), "--est", f"m={results}"]
    assert main(argv) == 0, capsys.readouterr().err
    capsys.readouterr()
    write_pfm(results / "Teddy" / "disp0m.pfm", gt)
    err = _one_line_error(capsys, argv)
    assert str(results / "Teddy.pfm") in err
    assert str(results / "Teddy" / "disp0m.pfm") in err
