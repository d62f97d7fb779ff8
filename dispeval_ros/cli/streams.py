"""Options and configuration shared by the commands that evaluate streams (bag, live)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from dispeval_ros.cli import common
from dispeval_ros.core.measures import SEQUENCE_MEASURES
from dispeval_ros.errors import ConfigurationError

if TYPE_CHECKING:
    from dispeval_ros.live.core import CoreConfig


def add_stream_options(
    parser: argparse.ArgumentParser, lateness_clock: str
) -> argparse._ArgumentGroup:
    """Topics, sync, evaluation and model options; returns the "run" group for the rest."""
    topics = parser.add_argument_group("topics")
    topics.add_argument(
        "--gt", required=True, metavar="TOPIC", help="ground-truth sensor_msgs/Image topic"
    )
    topics.add_argument(
        "--method",
        action="append",
        required=True,
        metavar="NAME=TOPIC",
        help="a method's stereo_msgs/DisparityImage topic; repeat for every method",
    )
    topics.add_argument(
        "--camera-info",
        nargs=2,
        metavar=("LEFT", "RIGHT"),
        help="left and right CameraInfo topics (f = P[0], B = -P_right[3]/P_right[0]); "
        "default: f and t of the DisparityImage",
    )
    topics.add_argument(
        "--gt-kind",
        choices=("disparity", "depth"),
        default="disparity",
        help="ground truth is disparity (32FC1 px, 16UC1 / scale) or depth (32FC1 m, 16UC1 mm)",
    )
    topics.add_argument(
        "--gt-scale", type=float, help="16-bit GT divisor (disparity default 256, depth 1000)"
    )
    topics.add_argument(
        "--tolerance", type=float, default=10.0, help="stamp join tolerance in ms (default 10)"
    )
    topics.add_argument(
        "--lateness",
        type=float,
        default=1000.0,
        help=f"how late (ms, in {lateness_clock}) an estimate may arrive after its ground truth "
        "(default 1000)",
    )
    common.add_evaluation_options(parser)
    run = parser.add_argument_group("run")
    run.add_argument(
        "--objectives",
        choices=("sequence", "frame"),
        default="sequence",
        help="model objectives per (criterion, sequence) (default) or per (criterion, frame)",
    )
    run.add_argument(
        "--objective-measures",
        nargs="+",
        default=["sze", "bmpre"],
        metavar="M",
        help="measures that form the objectives (default: sze bmpre)",
    )
    run.add_argument(
        "--out",
        type=Path,
        default=Path("dispeval-results"),
        help="results folder (default ./dispeval-results)",
    )
    return run


def _methods(specs: list[str]) -> dict[str, str]:
    methods: dict[str, str] = {}
    for spec in specs:
        name, sep, topic = spec.partition("=")
        if not sep or not name or not topic:
            raise ConfigurationError(
                f"--method '{spec}' is not NAME=TOPIC (e.g. sgbm=/stereo/sgbm/disparity)"
            )
        if name in methods:
            raise ConfigurationError(f"method name '{name}' is given twice")
        methods[name] = topic
    return methods


def core_config(args: argparse.Namespace, what: str) -> CoreConfig:
    """The evaluation core's configuration from the options (``what``: bags, live streams)."""
    from dispeval_ros.live.core import CoreConfig

    if args.depth_ranges:
        raise ConfigurationError(
            f"--depth-ranges is not available for {what} yet; use the 3-means depth criteria"
        )
    if args.measures is None:  # quantiles are opt-in for sequences: not summable, not cheap
        args.measures = list(SEQUENCE_MEASURES)
    evaluator = common.evaluator_from_args(args)
    left, right = args.camera_info if args.camera_info else (None, None)
    return CoreConfig(
        methods=_methods(args.method),
        gt_topic=args.gt,
        gt_kind=args.gt_kind,
        gt_scale=args.gt_scale,
        left_info_topic=left,
        right_info_topic=right,
        criteria=evaluator.criteria,
        measures=evaluator.measures,
        missing=evaluator.missing,
        delta=evaluator.delta,
        mu=evaluator.mu,
        tolerance_ns=round(args.tolerance * 1e6),
        lateness_ns=round(args.lateness * 1e6),
    )
