"""The configuration rules are checked once (CoreConfig) and worded with each front end's names.

One table of invalid configurations, built through ``dispeval bag``/``live`` argument lists and
through the ROS evaluator's parameter values: both front ends reject each one, in one line that
names the front end's own options (``--left-image``) or parameters (``parameter
left_image_topic``), never the other's.
"""

from __future__ import annotations

import contextlib
import io
from typing import Any

import pytest

from dispeval_ros.cli import streams
from dispeval_ros.cli.main import build_parser
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.ros import param_table, params
from dispeval_ros.stream.config import CoreConfig

METHODS = ["--method", "sgbm=/sgbm", "--method", "bm=/bm"]
IMAGES = ["--left-image", "/left", "--right-image", "/right"]
ROS_IMAGES = {"left_image_topic": "/left", "right_image_topic": "/right"}

Case = tuple[str, list[str] | None, dict[str, Any] | None, str, str]
CASES: list[Case] = [
    # (rule, CLI arguments (None: not expressible), ROS parameter changes, CLI words, ROS words)
    (
        "left image alone",
        ["--gt", "/gt", *METHODS, "--left-image", "/left"],
        {"left_image_topic": "/left"},
        "give both --left-image and --right-image, or neither",
        "give both parameters left_image_topic and right_image_topic, or neither",
    ),
    (
        "right image alone",
        ["--gt", "/gt", *METHODS, "--right-image", "/right"],
        {"right_image_topic": "/right"},
        "give both --left-image and --right-image, or neither",
        "give both parameters left_image_topic and right_image_topic, or neither",
    ),
    (
        "left image alone, no GT",
        [*METHODS, "--left-image", "/left"],
        {"gt_kind": "none", "gt_topic": "", "left_image_topic": "/left"},
        "give both --left-image and --right-image, or neither",
        "give both parameters left_image_topic and right_image_topic, or neither",
    ),
    (
        "one CameraInfo topic",
        None,  # --camera-info takes both
        {"left_camera_info": "/left/info"},
        "",
        "give both parameters left_camera_info and right_camera_info, or neither (then the "
        "camera comes from each DisparityImage's f and t)",
    ),
    (
        "empty GT topic",
        ["--gt", "", *METHODS],
        {"gt_topic": ""},
        "--gt is empty: name the ground-truth topic",
        "parameter gt_topic is empty: name the ground-truth topic",
    ),
    (
        "empty GT cloud topic",
        ["--gt-cloud", "", *METHODS, "--camera-info", "/l", "/r"],
        {
            "gt_topic": "",
            "gt_kind": "pointcloud",
            "left_camera_info": "/l",
            "right_camera_info": "/r",
        },
        "--gt-cloud is empty: name the ground-truth topic",
        "parameter gt_topic is empty: name the ground-truth topic",
    ),
    (
        "no GT, no images",
        [*METHODS],
        {"gt_kind": "none", "gt_topic": ""},
        "give the ground truth (--gt TOPIC or --gt-cloud TOPIC), or the rectified images",
        "parameter gt_kind is none: give parameters left_image_topic and right_image_topic",
    ),
    (
        "unknown GT kind",
        ["--gt", "/gt", *METHODS, "--gt-kind", "heights"],
        {"gt_kind": "heights"},
        "--gt-kind: invalid choice: 'heights'",
        "parameter gt_kind must be one of disparity, depth, pointcloud, none, got 'heights'",
    ),
    (
        "method given twice",
        ["--gt", "/gt", "--method", "sgbm=/a", "--method", "sgbm=/b"],
        {"methods": ("sgbm:/a", "sgbm:/b")},
        "--method: method 'sgbm' is given twice",
        "parameter methods: method 'sgbm' is given twice",
    ),
    (
        "right view given twice",
        [*IMAGES, *METHODS, "--right-view", "sgbm=/r1", "--right-view", "sgbm=/r2"],
        {
            "gt_kind": "none",
            "gt_topic": "",
            **ROS_IMAGES,
            "right_views": ("sgbm:/r1", "sgbm:/r2"),
        },
        "--right-view: method 'sgbm' is given twice",
        "parameter right_views: method 'sgbm' is given twice",
    ),
    (
        "two methods on one topic",
        ["--gt", "/gt", "--method", "a=/same", "--method", "b=/same"],
        {"methods": ("a:/same", "b:/same")},
        "two methods read the same topic",
        "two methods read the same topic",
    ),
    (
        "GT topic is a method's",
        ["--gt", "/sgbm", *METHODS],
        {"gt_topic": "/sgbm", "methods": ("sgbm:/sgbm",)},
        "the ground-truth topic /sgbm is also a method's topic",
        "the ground-truth topic /sgbm is also a method's topic",
    ),
    (
        "CameraInfo topic is the GT's",  # its type check would be skipped: every frame fails
        ["--gt", "/gt", *METHODS, "--camera-info", "/gt", "/r"],
        {"left_camera_info": "/gt", "right_camera_info": "/r"},
        "--camera-info LEFT /gt is also the ground-truth, an image or a disparity topic",
        "parameter left_camera_info /gt is also the ground-truth, an image or a disparity topic",
    ),
    (
        "CameraInfo topic is a method's",
        ["--gt", "/gt", *METHODS, "--camera-info", "/l", "/bm"],
        {"left_camera_info": "/l", "right_camera_info": "/bm"},
        "--camera-info RIGHT /bm is also the ground-truth, an image or a disparity topic",
        "parameter right_camera_info /bm is also the ground-truth, an image or a disparity topic",
    ),
    (
        "right view of an unknown method",
        [*IMAGES, *METHODS, "--right-view", "nobody=/r"],
        {"gt_kind": "none", "gt_topic": "", **ROS_IMAGES, "right_views": ("nobody:/r",)},
        "right-view disparity topics of unknown methods: nobody",
        "right-view disparity topics of unknown methods: nobody",
    ),
    (
        "right views without images",
        ["--gt", "/gt", *METHODS, "--right-view", "sgbm=/r"],
        {"right_views": ("sgbm:/r",)},
        "right-view disparities (for lrc) need the left and right image topics",
        "right-view disparities (for lrc) need the left and right image topics",
    ),
]


def cli_error(command: str, argv: list[str]) -> str:
    """The one-line refusal of ``dispeval COMMAND ARGV`` (argparse's or the configuration's)."""
    where = ["drive.mcap"] if command == "bag" else []
    stderr = io.StringIO()
    try:
        with contextlib.redirect_stderr(stderr):
            args = build_parser().parse_args([command, *where, *argv])
    except SystemExit:
        return stderr.getvalue().strip().splitlines()[-1]
    with pytest.raises(ConfigurationError) as error:
        streams.core_config(args, "bags" if command == "bag" else "live streams")
    return str(error.value)


def ros_error(changes: dict[str, Any]) -> str:
    values = {p.name: p.empty_default for p in param_table.EVALUATOR_PARAMETERS}
    values["methods"] = ("sgbm:/sgbm", "bm:/bm")
    values["gt_topic"] = "/gt"
    with pytest.raises(ConfigurationError) as error:
        params.core_config({**values, **changes})
    return str(error.value)


@pytest.mark.parametrize(
    ("rule", "argv", "ros", "cli_words", "ros_words"),
    CASES,
    ids=lambda c: c if isinstance(c, str) else "",
)
@pytest.mark.parametrize("command", ["bag", "live"])
def test_both_front_ends_reject_it_in_their_own_words(
    command: str,
    rule: str,
    argv: list[str] | None,
    ros: dict[str, Any],
    cli_words: str,
    ros_words: str,
) -> None:
    if argv is not None:
        message = cli_error(command, argv)
        assert cli_words in message
        assert "\n" not in message
        assert "parameter" not in message
    message = ros_error(ros)
    assert ros_words in message
    assert "\n" not in message
    assert "--" not in message


def test_python_callers_get_neutral_words() -> None:
    with pytest.raises(ConfigurationError, match=r"^give both the left image topic and the right"):
        CoreConfig(methods={"a": "/a"}, gt_topic="/gt", left_image_topic="/left")
    with pytest.raises(ConfigurationError, match=r"^the ground-truth topic is empty"):
        CoreConfig(methods={"a": "/a"}, gt_topic="")


def test_valid_cases_pass_in_both() -> None:
    """The table's base configurations are valid: each case fails for its own rule only."""
    assert streams.core_config(
        build_parser().parse_args(["bag", "drive.mcap", "--gt", "/gt", *METHODS]), "bags"
    ).methods == {"sgbm": "/sgbm", "bm": "/bm"}
    values = {p.name: p.empty_default for p in param_table.EVALUATOR_PARAMETERS}
    values.update(methods=("sgbm:/sgbm", "bm:/bm"), gt_topic="/gt")
    assert params.core_config(values).gt_topic == "/gt"
