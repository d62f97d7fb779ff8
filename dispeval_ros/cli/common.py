"""Argument parsing shared by the commands: criteria, measures, policy, camera."""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from dispeval_ros.core import (
    CRITERION_SETS,
    DEFAULT_CRITERIA,
    POLICIES,
    Camera,
    Evaluator,
    Scores,
    registry,
)
from dispeval_ros.core.gtfree import GT_FREE_CRITERION_SETS, GroundTruthFree, is_gt_free
from dispeval_ros.core.objectives import (
    DEFAULT_OBJECTIVES_TEXT,
    EGOMOTION_OBJECTIVES_TEXT,
    GT_FREE_OBJECTIVE,
    default_objective_measures,
    objective_matrix,
)
from dispeval_ros.core.timing import TIMING_MEASURES
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.summary import GRANULARITIES


def comma_list(text: str) -> list[str]:
    """``a,b c`` style lists: commas or repeated words."""
    return [part for part in text.replace(",", " ").split() if part]


#: The defaults of --missing and --delta.
DEFAULT_MISSING = "interpolate"
DEFAULT_DELTA = 1.0

_GIVEN = "_options_given"


class Given(argparse.Action):
    """Store the value and note that the option was written out.

    A ``--protocol`` that overrides an option refuses it whenever it is given, its default
    value written out (``--delta 1``) included: comparing with the default cannot tell.
    """

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: object,
        option_string: str | None = None,
    ) -> None:
        """Store ``values`` as ``store`` does and add the option to the ones given."""
        setattr(namespace, self.dest, values)
        setattr(namespace, _GIVEN, {*getattr(namespace, _GIVEN, ()), self.dest})


def given(args: argparse.Namespace, *dests: str) -> list[str]:
    """The options among ``dests`` (argparse names) written on the command line, in order."""
    written: set[str] = getattr(args, _GIVEN, set())
    return ["--" + dest.replace("_", "-") for dest in dests if dest in written]


def add_evaluation_options(parser: argparse.ArgumentParser) -> None:
    """Options that configure an :class:`Evaluator` (same names in every command)."""
    group = parser.add_argument_group("evaluation")
    group.add_argument(
        "--criteria",
        nargs="+",
        action=Given,
        default=list(DEFAULT_CRITERIA),
        metavar="SET",
        help=f"criterion sets: {', '.join(CRITERION_SETS)} (default: {' '.join(DEFAULT_CRITERIA)}); "
        "'legacy' adds the overlapping Middlebury nonocc/all/disc",
    )
    group.add_argument(
        "--measures",
        nargs="+",
        action=Given,
        default=None,
        metavar="M",
        help=f"measures (default: all): {registry.listing()}",
    )
    group.add_argument(
        "--missing",
        action=Given,
        choices=sorted(POLICIES),
        default=DEFAULT_MISSING,
        help="missing-estimate policy (default: interpolate, KITTI's background interpolation)",
    )
    group.add_argument(
        "--delta",
        type=float,
        action=Given,
        default=DEFAULT_DELTA,
        help="bad-pixel threshold δ in px (default 1)",
    )
    group.add_argument(
        "--mu",
        type=float,
        action=Given,
        default=0.01,
        help="SZE division guard μ in px (default 0.01)",
    )
    group.add_argument(
        "--depth-ranges",
        action=Given,
        default=None,
        metavar="A-B,...",
        help="metric depth criteria instead of 3-means, e.g. 0-10,10-30,30-inf (camera unit)",
    )


def add_camera_options(parser: argparse.ArgumentParser) -> None:
    """Camera from a calibration file or explicit values."""
    group = parser.add_argument_group("camera (for SZE in metres and metric depth ranges)")
    group.add_argument(
        "--calib", type=Path, help="calib.txt (Middlebury/ETH3D), KITTI calib, or Q.dat"
    )
    group.add_argument("--focal", type=float, help="focal length f in px")
    group.add_argument("--baseline", type=float, help="baseline B (metres)")
    group.add_argument(
        "--doffs", type=float, default=0.0, help="x-difference of principal points (px)"
    )


def parse_depth_ranges(text: str | None) -> list[tuple[float, float]] | None:
    """``0-10,10-30,30-inf`` → [(0, 10), (10, 30), (30, inf)]."""
    if not text:
        return None
    ranges = []
    for part in comma_list(text):
        pieces = part.split("-")
        try:
            if len(pieces) != 2:
                raise ValueError(part)
            ranges.append(
                (float(pieces[0]), math.inf if pieces[1] in ("inf", "") else float(pieces[1]))
            )
        except ValueError:
            raise ConfigurationError(
                f"depth range '{part}' is not of the form FROM-TO (e.g. 0-10 or 30-inf)"
            ) from None
    return ranges


LIDAR_DEPTH_RANGES = "0-10,10-30,30-inf"
"""The depth criteria of a scene whose GT is a LiDAR scan (metres)."""


def scene_defaults(args: argparse.Namespace, layout: str) -> None:
    """A LiDAR scene (``kitti-lidar``): metric depth ranges and the depth measures, unless given.

    A scan is sparse and metric, so depth bands in metres say more than 3-means clusters of its
    disparities; ``eval --scene`` and ``tune`` score such scenes the same way.
    """
    from dispeval_ros.core.measures import DEFAULT_MEASURES, DEPTH_MEASURES

    if layout != "kitti-lidar":
        return
    args.depth_ranges = args.depth_ranges or LIDAR_DEPTH_RANGES
    if args.measures is None:
        args.measures = [*DEFAULT_MEASURES, *DEPTH_MEASURES]


def evaluator_from_args(
    args: argparse.Namespace, roi_names: dict[int, str] | None = None
) -> Evaluator:
    """The evaluator the options describe."""
    criteria: list[str] = []
    for item in args.criteria:
        criteria.extend(comma_list(item))
    measures: list[str] | None = None
    if args.measures:
        measures = []
        for item in args.measures:
            measures.extend(comma_list(item))
    return Evaluator(
        criteria=criteria,
        measures=measures,
        missing=args.missing,
        delta=args.delta,
        mu=args.mu,
        depth_ranges=parse_depth_ranges(args.depth_ranges),
        roi_names=roi_names,
    )


def camera_from_args(args: argparse.Namespace) -> Camera | None:
    """Camera from ``--calib`` or ``--focal/--baseline/--doffs`` (None if neither)."""
    from dispeval_ros.io import read_calib

    explicit = args.focal is not None or args.baseline is not None
    if args.calib is not None and explicit:
        raise ConfigurationError("give either --calib or --focal/--baseline, not both")
    if args.calib is not None:
        return read_calib(args.calib)
    if explicit:
        if args.focal is None or args.baseline is None:
            raise ConfigurationError("--focal and --baseline go together (and --doffs if not 0)")
        return Camera(f=args.focal, baseline=args.baseline, doffs=args.doffs)
    return None


def add_objective_options(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup, default: str | None = "sequence"
) -> None:
    """``--objectives`` and ``--objective-measures``: what the models compare over frames.

    ``default`` None: the command takes the stored run's granularity (``report``).
    """
    parser.add_argument(
        "--objectives",
        choices=GRANULARITIES,
        default=default,
        help="model objectives per (criterion, sequence) or per (criterion, frame) (default: "
        + (f"{default})" if default else "the stored run's)"),
    )
    parser.add_argument(
        "--objective-measures",
        nargs="+",
        action=Given,
        default=None,
        metavar="M",
        help="measures that form the objectives, each on the criteria it is defined on "
        f"(default: {DEFAULT_OBJECTIVES_TEXT}; add vpe to rank on it beside the GT measures); "
        f"timing measures of stored results ({', '.join(TIMING_MEASURES)}) add one objective "
        "per sequence; the pair measures of --temporal (tepe...) and, on gtfree: criteria, the "
        "ego-motion residual of --egomotion, temporal noise without ground truth, not accuracy: "
        + EGOMOTION_OBJECTIVES_TEXT.replace("%", "%%"),  # (argparse formats help with %)
    )


def add_gt_free_criteria_option(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """``--gt-free-criteria``: the criterion sets of the ground-truth-free measures."""
    from dispeval_ros.core.gtfree import DEFAULT_GT_FREE_CRITERIA

    parser.add_argument(
        "--gt-free-criteria",
        nargs="+",
        default=list(DEFAULT_GT_FREE_CRITERIA),
        metavar="SET",
        help="criterion sets of the ground-truth-free measures (vpe, lrc): "
        f"{', '.join(GT_FREE_CRITERION_SETS)} (default: {' '.join(DEFAULT_GT_FREE_CRITERIA)})",
    )


def add_gt_free_options(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """``--gt-free-criteria`` and ``--gt-free-objectives`` (measures from the images alone)."""
    add_gt_free_criteria_option(parser)
    parser.add_argument(
        "--gt-free-objectives",
        action="store_true",
        help="with ground truth, also rank the methods on vpe (never mixed in otherwise)",
    )


def gt_free_criteria(args: argparse.Namespace) -> list[str]:
    """The ``--gt-free-criteria`` sets (checked by :class:`GroundTruthFree`)."""
    return [name for item in args.gt_free_criteria for name in comma_list(item)]


def gt_free_from_args(
    args: argparse.Namespace, roi_names: dict[int, str] | None = None
) -> GroundTruthFree:
    """The ground-truth-free scorer the options describe (same missing policy as the GT)."""
    criteria = gt_free_criteria(args)
    return GroundTruthFree(criteria, args.missing, roi_names=roi_names)


def model_objectives(
    results: Mapping[str, Scores], measures: Sequence[str], gt_free_too: bool = False
) -> tuple[list[str], list[str], np.ndarray] | None:
    """Methods, objective names and matrix: GT objectives, else (or if asked, also) vpe.

    GT-free criteria are never objectives beside GT ones unless ``gt_free_too``; overlapping
    legacy criteria never are. None when nothing is comparable.
    """
    first = next(iter(results.values()))
    comparable = [c for c in first.criteria if c not in first.overlapping]
    gt = [c for c in comparable if not is_gt_free(c)]
    free = [c for c in comparable if is_gt_free(c)]
    parts = []
    if gt:
        parts.append(objective_matrix(results, default_objective_measures(measures), gt))
    if free and (gt_free_too or not gt):
        parts.append(objective_matrix(results, [GT_FREE_OBJECTIVE], free))
    if not parts:
        return None
    return (
        parts[0][0],
        [name for part in parts for name in part[1]],
        np.hstack([part[2] for part in parts]),
    )


def positive_option(value: float | None, option: str) -> float | None:
    """A scale-like option: absent, or a finite number > 0 (one line naming the option)."""
    if value is not None and not (math.isfinite(value) and value > 0):
        raise ConfigurationError(
            f"{option} must be a finite number > 0 (leave it out for the default), got {value:g}"
        )
    return value
