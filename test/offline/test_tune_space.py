"""The parameter space of ``dispeval tune``: names, expansion, sampling, refusals, YAML output.

Expected values are written here from stereo_image_proc's declarations (names, ranges,
defaults of ``disparity_node.cpp``), not read from the project's table.
"""

from __future__ import annotations

import itertools
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from refusal_support import assert_refused

from dispeval_ros.cli.main import main
from dispeval_ros.offline.tuning.space import space_from_document
from dispeval_ros.testbed.node_parameters import params_document

# stereo_image_proc (ROS 2) disparity node: declared defaults
SGBM_DEFAULTS = {
    "prefilter_cap": 31,
    "correlation_window_size": 15,
    "min_disparity": 0,
    "disparity_range": 64,
    "speckle_size": 100,
    "speckle_range": 4,
    "disp12_max_diff": 0,
    "sgbm_mode": 0,
    "uniqueness_ratio": 15,
    "P1": 200,
    "P2": 400,
}
BM_DEFAULTS = {
    "prefilter_size": 9,
    "prefilter_cap": 31,
    "correlation_window_size": 15,
    "min_disparity": 0,
    "disparity_range": 64,
    "texture_threshold": 10,
    "speckle_size": 100,
    "speckle_range": 4,
    "uniqueness_ratio": 15,
}


def space(family: str = "sgbm", **parameters: object) -> dict[str, object]:
    return {"family": family, "parameters": parameters}


def test_grid_is_every_combination_named_by_the_values_that_vary() -> None:
    configurations = space_from_document(
        space(correlation_window_size=[5, 9], P2=[800, 1200], speckle_range=2), "s"
    ).configurations()
    expected = [
        (
            f"sgbm_w{w}_p2{p2}",
            {**SGBM_DEFAULTS, "correlation_window_size": w, "P2": p2, "speckle_range": 2},
        )
        for w, p2 in itertools.product([5, 9], [800, 1200])
    ]
    assert [(c.name, c.values) for c in configurations] == expected


def test_a_range_takes_every_value_of_the_node_step_by_default() -> None:
    parsed = space_from_document(
        space(
            correlation_window_size={"min": 5, "max": 9},
            disparity_range={"min": 32, "max": 64},
            uniqueness_ratio={"min": 5, "max": 15, "step": 5},
            sgbm_mode={"choices": [0, 3]},
        ),
        "s",
    )
    assert parsed.axes == {
        "correlation_window_size": [5, 7, 9],
        "disparity_range": [32, 48, 64],
        "uniqueness_ratio": [5, 10, 15],
        "sgbm_mode": [0, 3],
    }
    assert parsed.size == 54


def test_seeded_sampling_draws_distinct_grid_points_reproducibly() -> None:
    parsed = space_from_document(
        space(
            correlation_window_size={"min": 5, "max": 21},
            uniqueness_ratio={"min": 0, "max": 30},
            speckle_size={"min": 0, "max": 200, "step": 50},
        ),
        "s",
    )
    grid = [c.name for c in parsed.configurations()]
    first = [c.name for c in parsed.configurations(samples=40, seed=7)]
    assert first == [c.name for c in parsed.configurations(samples=40, seed=7)]
    assert len(set(first)) == 40
    assert set(first) <= set(grid)
    assert first == sorted(first, key=grid.index)  # listed in grid order
    assert first != [c.name for c in parsed.configurations(samples=40, seed=8)]
    assert [c.name for c in parsed.configurations(samples=10_000, seed=1)] == grid


def test_params_file_types_and_family_parameters() -> None:
    sgbm = params_document("disparity_node", "sgbm", SGBM_DEFAULTS)
    values = sgbm["disparity_node"]["ros__parameters"]
    assert values == {"stereo_algorithm": 1, **SGBM_DEFAULTS}
    assert {k for k, v in values.items() if isinstance(v, float)} == {
        "uniqueness_ratio",
        "P1",
        "P2",
    }
    bm = params_document("stereo/disparity", "bm", BM_DEFAULTS)["stereo/disparity"]
    assert bm["ros__parameters"] == {"stereo_algorithm": 0, **BM_DEFAULTS}


def test_bm_matcher_is_what_the_node_runs() -> None:
    """BM as the node sets it: XSOBEL prefilter, disp12MaxDiff left at OpenCV's -1."""
    rng = np.random.default_rng(3)
    right = rng.integers(0, 256, size=(120, 200), dtype=np.uint8)
    left = np.roll(right, 7, axis=1)
    chosen = {"correlation_window_size": 11, "texture_threshold": 5, "speckle_size": 0}
    (configuration,) = space_from_document(
        space("bm", correlation_window_size=[11], texture_threshold=[5, 6], speckle_size=0), "s"
    ).configurations()[:1]
    p = {**BM_DEFAULTS, **chosen}
    bm = cv2.StereoBM.create(p["disparity_range"], p["correlation_window_size"])
    bm.setPreFilterSize(p["prefilter_size"])
    bm.setPreFilterCap(p["prefilter_cap"])
    bm.setTextureThreshold(p["texture_threshold"])
    bm.setUniquenessRatio(p["uniqueness_ratio"])
    bm.setSpeckleWindowSize(p["speckle_size"])
    bm.setSpeckleRange(p["speckle_range"])
    raw = bm.compute(left, right)
    expected = raw.astype(np.float32) / 16
    expected[raw < 0] = -1
    assert configuration.values == p
    assert np.array_equal(configuration.method.compute(left, right), expected)
    assert np.count_nonzero(expected == 7) > 1000


REFUSED = [
    ("family: sgbm\nparameters: {foo: [1, 2]}", "unknown parameter 'foo'"),
    ("family: sgbm\nparameters: {correlation_window_size: [4, 5]}", "(odd), got 4"),
    ("family: sgbm\nparameters: {P1: 400, P2: [300, 800]}", "P2 must be greater than P1"),
    ("family: sgbm\nparameters: {disparity_range: [40, 64]}", "a multiple of 16"),
    ("family: sgbm\nparameters: {correlation_window_size: []}", "no values"),
    ("family: sgbm\nparameters: {}", "the space is empty"),
    ("family: sgbm", "the space is empty"),
    ("family: sgbm\nparameters: {speckle_size: {min: 9, max: 5}}", "the range is empty"),
    ("family: sgbm\nparameters: {texture_threshold: [1, 2]}", "reaches only the BM matcher"),
    ("family: bm\nparameters: {P1: [1, 2]}", "reaches only the SGBM matcher"),
    ("family: elas\nparameters: {P1: [1, 2]}", "family must be bm or sgbm"),
    ("family: sgbm\nparameters: {correlation_window_size: 5}", "holds 1 configuration"),
    ("family: sgbm\nparameters: {uniqueness_ratio: [10.5, 11]}", "whole number"),
    ("family: sgbm\nparameters: {P1: [0, 10]}", "P1 must be in [1, 4000]"),
    ("family: sgbm\nparameters: {sgbm_mode: [0, 4]}", "sgbm_mode must be in [0, 3]"),
    ("family: sgbm\nparameters: {speckle_size: {from: 1}}", "expected a value, a list"),
    ("family: [", "cannot parse the space file"),
    ("- 1\n- 2", "expected a mapping"),
    ("family: sgbm\nspace: {}\nparameters: {P1: [1, 2]}", "unknown key(s) space"),
]


@pytest.mark.parametrize(("text", "needle"), REFUSED)
def test_a_bad_space_is_one_line_and_leaves_nothing(
    text: str, needle: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "space.yaml"
    path.write_text(text)
    out = tmp_path / "out"
    code = main(["tune", "--space", str(path), "--scene", str(tmp_path), "--out", str(out)])
    assert_refused(code, capsys.readouterr().err, needle)
    assert not out.exists()


def _good_space(folder: Path) -> Path:
    path = folder / "space.yaml"
    path.write_text("family: sgbm\nparameters: {correlation_window_size: [5, 7]}")
    return path


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--jobs", "0"], "--jobs must be at least 1"),
        (["--jobs", "2", "--scheduler", "local:2"], "give --jobs or --scheduler, not both"),
        (["--scheduler", "ws://x:1"], "--scheduler ws://x:1"),
        (["--chunk", "0"], "--chunk must be at least 1"),
        (["--samples", "1"], "--samples must be at least 2"),
        (["--node-name", "a b"], "--node-name must be a ROS node name"),
        (["--node", "/x", "--jobs", "2"], "--jobs and --scheduler do not apply"),
        (["--timeout", "1"], "--node-namespace and --timeout apply to --node only"),
        (["--node", "/x", "--timeout", "0"], "--timeout must be a positive number"),
    ],
)
def test_bad_options_are_one_line_and_leave_nothing(
    extra: list[str], needle: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    argv = ["--space", str(_good_space(tmp_path)), "--scene", str(tmp_path), "--out", str(out)]
    code = main(["tune", *argv, *extra])
    assert_refused(code, capsys.readouterr().err, needle)
    assert not out.exists()


@pytest.mark.parametrize("kind", ["missing", "empty"])
def test_a_bad_scene_is_one_line_naming_it_and_leaves_nothing(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scene = tmp_path / kind
    if kind == "empty":
        scene.mkdir()
    out = tmp_path / "out"
    code = main(
        ["tune", "--space", str(_good_space(tmp_path)), "--scene", str(scene), "--out", str(out)]
    )
    assert_refused(code, capsys.readouterr().err, str(scene))
    assert not out.exists()


def test_tune_node_without_rclpy_is_one_line_and_leaves_nothing(
    shared_data: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setitem(sys.modules, "dispeval_ros.ros.tune_node", None)  # import fails
    out = tmp_path / "out"
    scene = shared_data / "middeval3-training-Q" / "ArtL"
    argv = ["--space", str(_good_space(tmp_path)), "--scene", str(scene), "--out", str(out)]
    code = main(["tune", *argv, "--node", "/disparity_node"])
    assert_refused(code, capsys.readouterr().err, "tune --node needs ROS 2's rclpy")
    assert not out.exists()


def test_a_missing_space_file_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(
        ["tune", "--space", str(tmp_path / "no.yaml"), "--scene", ".", "--out", str(tmp_path / "o")]
    )
    assert_refused(code, capsys.readouterr().err, "no.yaml: cannot read the space file")


def test_the_bundled_example_space_is_the_3_by_3_by_2_sgbm_grid() -> None:
    from dispeval_ros.offline.tuning.space import read_space

    example = read_space(Path(__file__).resolve().parents[2] / "config" / "tune_sgbm.yaml")
    configurations = example.configurations()
    assert len(configurations) == 18
    assert configurations[0].name == "sgbm_w5_u5_mode0"


def test_a_unit_lost_on_its_worker_is_one_line_saying_how_to_continue() -> None:
    from concurrent.futures import Future
    from concurrent.futures.process import BrokenProcessPool

    from dispeval_ros.errors import InputError
    from dispeval_ros.offline.tuning.sweep import TuneUnit, _result

    lost: Future[object] = Future()
    lost.set_exception(BrokenProcessPool("A process in the process pool was\nterminated"))
    unit = TuneUnit(0, "ArtL", "000001", ())
    with pytest.raises(InputError) as raised:
        _result(lost, unit)
    message = str(raised.value)
    assert "\n" not in message
    assert message.startswith("unit 000001 of ArtL failed on its worker (BrokenProcessPool: A ")
    assert message.endswith("continue with --resume")
    refused: Future[object] = Future()
    refused.set_exception(InputError("scene: no images"))
    with pytest.raises(InputError, match=r"^scene: no images$"):
        _result(refused, unit)
