"""Options and configuration shared by the commands that evaluate streams (bag, live)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from dispeval_ros.cli import common, confidence_eval
from dispeval_ros.core.objectives import (
    default_objective_measures,
    is_egomotion_measure,
    is_pair_measure,
)
from dispeval_ros.core.projection import CloudFilter
from dispeval_ros.core.timing import TIMING_MEASURES, is_timing_measure
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.stream.config import FieldNames, core_default, default_measures
from dispeval_ros.stream.join import LATENESS_RULE
from dispeval_ros.stream.pairs import DRIFT_RULE, PAIR_GAP_RULE

if TYPE_CHECKING:
    from dispeval_ros.stream.core import CoreConfig

_NS_PER_MS = 1_000_000


def add_stream_options(
    parser: argparse.ArgumentParser, egomotion: bool = False
) -> argparse._ArgumentGroup:
    """Topics, sync, evaluation and model options; returns the "run" group for the rest.

    ``egomotion``: also ``--egomotion`` (the commands that read /tf over time).
    """
    topics = parser.add_argument_group("topics")
    gt = topics.add_mutually_exclusive_group()
    gt.add_argument("--gt", metavar="TOPIC", help="ground-truth sensor_msgs/Image topic")
    gt.add_argument(
        "--gt-cloud",
        metavar="TOPIC",
        help="ground truth from a LiDAR: a sensor_msgs/PointCloud2 topic projected into the "
        "left camera (needs --camera-info; the extrinsic comes from /tf_static or --extrinsic)",
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
        default=core_default("gt_kind"),
        help="ground truth is disparity (32FC1 px, 16UC1 / scale) or depth (32FC1 m, 16UC1 mm)",
    )
    topics.add_argument(
        "--gt-scale", type=float, help="16-bit GT divisor (disparity default 256, depth 1000)"
    )
    topics.add_argument(
        "--extrinsic",
        type=Path,
        metavar="FILE",
        help="with --gt-cloud: the cloud → left camera transform (a 4×4 matrix or "
        "'x y z qx qy qz qw') instead of /tf_static",
    )
    topics.add_argument(
        "--cloud-filter",
        default=core_default("cloud_filter"),
        metavar="W,G",
        help="with --gt-cloud: drop a point when a point in its W×W pixel window is nearer by "
        f"more than the relative gap G (LiDAR–camera parallax); '0' disables "
        f"(default {core_default('cloud_filter')})",
    )
    topics.add_argument(
        "--left-image",
        metavar="TOPIC",
        help="left rectified sensor_msgs/Image (mono8, rgb8, bgr8): with --right-image, the "
        "ground-truth-free measures vpe and lrc (then --gt may be left out)",
    )
    topics.add_argument("--right-image", metavar="TOPIC", help="right rectified sensor_msgs/Image")
    topics.add_argument(
        "--right-view",
        action="append",
        default=[],
        metavar="NAME=TOPIC",
        help="a method's right-view DisparityImage topic, for its left-right inconsistency (lrc)",
    )
    common.add_gt_free_criteria_option(topics)
    confidence_eval.add_input_options(
        parser.add_argument_group("confidence maps (sparsification, AUC, AUSE)"),
        "NAME=TOPIC",
        "a method's confidence map, a sensor_msgs/Image topic joined by stamp with its estimate "
        "(needs a ground truth)",
    )
    tolerance_ms = core_default("tolerance_ns") / _NS_PER_MS
    topics.add_argument(
        "--tolerance",
        type=float,
        default=tolerance_ms,
        help=f"stamp join tolerance in ms (default {tolerance_ms:g})",
    )
    lateness_ms = core_default("lateness_ns") / _NS_PER_MS
    topics.add_argument(
        "--lateness",
        type=float,
        default=lateness_ms,
        help=f"{LATENESS_RULE} (ms, default {lateness_ms:g})",
    )
    common.add_evaluation_options(parser)
    add_temporal_options(parser.add_argument_group("temporal"), egomotion)
    run = parser.add_argument_group("run")
    common.add_objective_options(run)
    run.add_argument(
        "--out",
        type=Path,
        default=Path("dispeval-results"),
        help="results folder (default ./dispeval-results)",
    )
    return run


def add_temporal_options(group: argparse._ArgumentGroup, egomotion: bool = False) -> None:
    """``--temporal [PRESET]`` (the option of ``eval``), ``--pair-gap MS``, ``--egomotion``."""
    from dispeval_ros.cli import temporal_eval

    temporal_eval.add_options(group, "over each sequence's consecutive ground-truth frames")
    gap_ms = core_default("pair_gap_ns") / _NS_PER_MS
    group.add_argument(
        "--pair-gap",
        type=float,
        default=gap_ms,
        metavar="MS",
        help=f"with --temporal, --egomotion or --flicker: {PAIR_GAP_RULE} (ms, default {gap_ms:g})",
    )
    if egomotion:
        group.add_argument(
            "--egomotion",
            action="store_true",
            help="also score each method's ego-motion residual over the same pairs (temporal "
            "noise without GT, on gtfree: criteria: frame t's estimate moved into frame t+1 by "
            "the camera's motion from /tf and /tf_static; needs --camera-info; docs/method.md); "
            + DRIFT_RULE,
        )
        add_flicker_option(group)


def add_flicker_option(group: argparse._ArgumentGroup) -> None:
    """``--flicker [N]``: off by default, N frames per window when given alone (bags, live)."""
    from dispeval_ros.stream.flicker import DEFAULT_FLICKER_WINDOW, FLICKER_RULE

    group.add_argument(
        "--flicker",
        type=int,
        nargs="?",
        const=DEFAULT_FLICKER_WINDOW,
        default=core_default("flicker"),
        metavar="N",
        help=f"{FLICKER_RULE} (N default {DEFAULT_FLICKER_WINDOW}; assumes a static camera, "
        "checked against /tf with --egomotion; docs/method.md)",
    )


_NAMES = {
    "methods": "--method",
    "right_views": "--right-view",
    "confidences": "--confidence",
    "confidence_presets": "--confidence-preset",
    "gt_kind": "--gt-kind",
    "left_info_topic": "--camera-info LEFT",
    "right_info_topic": "--camera-info RIGHT",
    "left_image_topic": "--left-image",
    "right_image_topic": "--right-image",
    "temporal": "--temporal",
    "pair_gap_ns": "--pair-gap",
    "egomotion": "--egomotion",
    "flicker": "--flicker",
}
"""How the options name :class:`CoreConfig`'s fields in its errors (``gt_topic``: see below)."""


def field_names(cloud: bool) -> FieldNames:
    """The CLI's names of the configuration fields (the GT topic is --gt or --gt-cloud)."""
    return FieldNames({**_NAMES, "gt_topic": "--gt-cloud" if cloud else "--gt"})


def _methods(specs: list[str], about: str, names: FieldNames) -> dict[str, str]:
    pairs = []
    for spec in specs:
        name, sep, topic = spec.partition("=")
        if not sep or not name or not topic:
            raise ConfigurationError(
                f"{names.of(about)} '{spec}' is not NAME=TOPIC (e.g. sgbm=/stereo/sgbm/disparity)"
            )
        pairs.append((name, topic))
    return names.unique(pairs, about)


def core_config(args: argparse.Namespace, what: str) -> CoreConfig:
    """The evaluation core's configuration from the options (``what``: bags, live streams)."""
    from dispeval_ros.stream.core import CoreConfig

    if args.depth_ranges:
        raise ConfigurationError(
            f"--depth-ranges is not available for {what} yet; use the 3-means depth criteria"
        )
    cloud = args.gt_cloud is not None
    if not cloud and (
        args.extrinsic is not None or args.cloud_filter != core_default("cloud_filter")
    ):
        raise ConfigurationError("--extrinsic and --cloud-filter go with --gt-cloud")
    if args.gt is None and args.gt_kind != core_default("gt_kind"):
        raise ConfigurationError(
            f"--gt-kind {args.gt_kind} does not apply "
            + ("with --gt-cloud (the cloud gives depth points)" if cloud else "without --gt")
            + ": it is the encoding of the --gt image topic"
        )
    names = field_names(cloud)
    has_gt = cloud or args.gt is not None
    if not has_gt and args.left_image is None and args.right_image is None:
        raise ConfigurationError(
            "give the ground truth (--gt TOPIC or --gt-cloud TOPIC), or the rectified images "
            "(--left-image TOPIC --right-image TOPIC) for the ground-truth-free measures"
        )
    gt_free_criteria = common.gt_free_criteria(args)
    if args.measures is None:  # named, so that they are stored with the results
        args.measures = list(default_measures(cloud))
    evaluator = common.evaluator_from_args(args)
    left, right = args.camera_info if args.camera_info else (None, None)
    extrinsic = None
    if args.extrinsic is not None:
        from dispeval_ros.io.lidar import read_extrinsic

        extrinsic = tuple(float(v) for v in read_extrinsic(args.extrinsic).reshape(-1))
    confidences = _methods(args.confidence, "confidences", names)
    config = CoreConfig(
        methods=_methods(args.method, "methods", names),
        confidences=confidences,
        confidence_presets=confidence_eval.stream_presets(args, confidences),
        gt_topic=args.gt_cloud if cloud else (args.gt if has_gt else args.left_image),
        gt_kind="pointcloud" if cloud else (args.gt_kind if has_gt else "none"),
        left_image_topic=args.left_image,
        right_image_topic=args.right_image,
        right_views=_methods(args.right_view, "right_views", names),
        gt_free_criteria=tuple(gt_free_criteria),
        extrinsic=extrinsic,
        cloud_filter=str(CloudFilter.parse(args.cloud_filter)),
        gt_scale=common.positive_option(args.gt_scale, "--gt-scale"),
        left_info_topic=left,
        right_info_topic=right,
        criteria=evaluator.criteria,
        measures=evaluator.measures,
        missing=evaluator.missing,
        delta=evaluator.delta,
        mu=evaluator.mu,
        tolerance_ns=round(non_negative_ms(args.tolerance, "--tolerance") * _NS_PER_MS),
        lateness_ns=round(non_negative_ms(args.lateness, "--lateness") * _NS_PER_MS),
        temporal=args.temporal,
        egomotion=bool(getattr(args, "egomotion", False)),  # bag and live
        flicker=getattr(args, "flicker", 0) or 0,
        pair_gap_ns=round(non_negative_ms(args.pair_gap, "--pair-gap") * _NS_PER_MS),
        names=names,
    )
    if args.objective_measures is None:  # follow the measures scored (vpe without GT)
        args.objective_measures = default_objective_measures(config.scored_measures)
    pairs = config.pair_stage()
    paired = pairs.scorer.measures if pairs is not None and pairs.scorer is not None else ()
    unknown = [
        m
        for m in args.objective_measures
        if m not in config.scored_measures
        and not is_timing_measure(m)
        and m not in paired
        and not (config.egomotion and is_egomotion_measure(m))
    ]
    if unknown:  # found now, not after the whole recording was scored
        temporal = (
            f", nor pair measures ({', '.join(paired)})"
            if paired
            else " (pair measures need --temporal)"
            if any(map(is_pair_measure, unknown))
            else ""
        )
        if any(map(is_egomotion_measure, unknown)):
            temporal += " (ego-motion residual measures need --egomotion)"
        raise ConfigurationError(
            f"--objective-measures {' '.join(unknown)}: not among the measures scored "
            f"({', '.join(config.scored_measures)}) nor timing ({', '.join(TIMING_MEASURES)})"
            + temporal
        )
    return config


def non_negative_ms(value: float, option: str) -> float:
    """A time option in ms: a finite number ≥ 0 (one line naming the option)."""
    if not (math.isfinite(value) and value >= 0):
        raise ConfigurationError(f"{option} must be a number of ms ≥ 0, got {value:g}")
    return value
