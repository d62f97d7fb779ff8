"""Options that would change nothing are refused in one line, never silently ignored.

``--gt-kind`` is the encoding of the ``--gt`` image topic: with ``--gt-cloud`` (depth points)
or without any GT it has nothing to act on. A camera-info topic that is another configured
topic escaped the bag's type check and failed every frame: refused up front (exit 2).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from refusal_support import assert_refused

from dispeval_ros.cli import streams
from dispeval_ros.cli.main import build_parser, main
from dispeval_ros.errors import ConfigurationError

METHODS = ["--method", "sgbm=/sgbm"]


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--gt-cloud", "/points", "--camera-info", "/l", "/r"], "with --gt-cloud"),
        (["--left-image", "/left", "--right-image", "/right"], "without --gt"),
    ],
)
@pytest.mark.parametrize("command", ["bag", "live"])
def test_gt_kind_without_a_gt_image_is_refused(command: str, argv: list[str], words: str) -> None:
    where = ["drive.mcap"] if command == "bag" else []
    args = build_parser().parse_args([command, *where, *argv, *METHODS, "--gt-kind", "depth"])
    with pytest.raises(ConfigurationError) as error:
        streams.core_config(args, "bags")
    message = str(error.value)
    assert f"--gt-kind depth does not apply {words}" in message
    assert "\n" not in message


def test_gt_kind_with_a_gt_image_is_used() -> None:
    args = build_parser().parse_args(["bag", "x", "--gt", "/gt", *METHODS, "--gt-kind", "depth"])
    assert streams.core_config(args, "bags").gt_kind == "depth"


def test_camera_info_naming_an_image_topic_exits_2_before_reading(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The bag need not exist: the configuration is refused before it is opened."""
    code = main(
        [
            "bag",
            str(tmp_path / "absent.mcap"),
            *("--left-image", "/left", "--right-image", "/right"),
            *("--camera-info", "/left", "/right"),
            *METHODS,
            *("--out", str(tmp_path / "out")),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2
    assert "--camera-info LEFT /left is also the ground-truth, an image or a disparity topic" in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "option",
    [
        ("--delta", "1"),  # the default, written out: refused as any other value
        ("--delta", "2"),
        ("--missing", "interpolate"),
        ("--missing", "ignore"),
        ("--criteria", "all"),
        ("--measures", "bmp"),
        ("--mu", "0.01"),
        ("--depth-ranges", "0-10"),
    ],
)
def test_eval_protocol_refuses_a_project_option_whatever_its_value(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: tuple[str, str]
) -> None:
    argv = ["eval", "--protocol", "middeval3", "--scene", str(tmp_path), "--est", "X", *option]
    code = main(argv)
    assert_refused(code, capsys.readouterr().err, f"{option[0]} does not apply with --protocol")


def test_eval_protocol_without_project_options_goes_on(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The control: left out, no option is reported (the empty scene folder is what stops)."""
    code = main(["eval", "--protocol", "middeval3", "--scene", str(tmp_path), "--est", "X"])
    err = capsys.readouterr().err
    assert code == 2
    assert "does not apply" not in err


@pytest.mark.parametrize(
    "option",
    [
        ("--missing", "interpolate"),
        ("--criteria", "all"),
        ("--measures", "bad_2"),
        ("--objective-measures", "bad_2"),
    ],
)
def test_bag_protocol_refuses_an_option_its_preset_sets(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: tuple[str, str]
) -> None:
    """The preset sets these: one given is refused (the default written out too), nothing made."""
    argv = [
        "bag",
        str(tmp_path / "absent.mcap"),
        "--gt",
        "/gt",
        *METHODS,
        "--protocol",
        "kitti2012",
    ]
    code = main([*argv, "--out", str(tmp_path / "out"), *option])
    err = capsys.readouterr().err
    assert_refused(code, err, f"{option[0]} does not apply with --protocol kitti2012")
    assert not (tmp_path / "out").exists()
