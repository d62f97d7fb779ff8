"""``dispeval bag``: evaluate recorded stereo streams (rosbag2 sqlite3/MCAP, ROS 1, MCAP)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from dispeval_ros.cli import common
from dispeval_ros.cli.output import print_json
from dispeval_ros.cli.progress import Progress
from dispeval_ros.cli.summary import run_summary_text
from dispeval_ros.core.measures import SEQUENCE_MEASURES
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.jsonio import write_json

if TYPE_CHECKING:
    from dispeval_ros.live.core import CoreConfig

HELP = "evaluate the stereo methods recorded in bags, frame by frame, into a results database"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``bag``."""
    parser = subparsers.add_parser(
        "bag",
        help=HELP,
        description=HELP + ". Each bag is one sequence. Frames of each method are joined to the "
        "ground truth by header stamp; per-frame rows go to DIR/results.sqlite as the run goes, "
        "then DIR/frames.csv and DIR/summary.json, and the per-sequence summary is printed.",
    )
    parser.add_argument(
        "bags",
        nargs="+",
        type=Path,
        metavar="BAG",
        help="rosbag2 folder, .mcap, .db3 or ROS 1 .bag",
    )
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
        help="how late (ms, in log time) an estimate may arrive after its ground truth (default 1000)",
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
    run.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    run.add_argument("--resume", action="store_true", help="continue an interrupted run in --out")
    run.add_argument(
        "--slice", type=float, default=5.0, help="seconds of bag per unit of work (default 5)"
    )
    run.add_argument("--quiet", action="store_true", help="no progress line")
    run.add_argument("--json", action="store_true", help="print the summary as JSON")
    parser.set_defaults(run=run_command)


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


def core_config(args: argparse.Namespace) -> CoreConfig:
    """The evaluation core's configuration from the options."""
    from dispeval_ros.live.core import CoreConfig

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


def run_command(args: argparse.Namespace) -> int:
    """Evaluate, export, summarise."""
    from dispeval_ros.io.store import ResultsStore
    from dispeval_ros.offline.bag_eval import evaluate_bags
    from dispeval_ros.offline.summary import summarize

    config = core_config(args)
    if args.depth_ranges:
        raise ConfigurationError(
            "--depth-ranges is not available for bags yet; use the 3-means depth criteria"
        )
    slice_ns = round(args.slice * 1e9)
    if slice_ns <= 0:
        raise ConfigurationError(f"--slice must be positive, got {args.slice}")
    record = {
        "methods": dict(config.methods),
        "gt_topic": config.gt_topic,
        "gt_kind": config.gt_kind,
        "gt_scale": config.gt_scale,
        "camera_info": [config.left_info_topic, config.right_info_topic],
        "criteria": list(config.criteria),
        "measures": list(config.measures or []),
        "missing": config.missing,
        "delta": config.delta,
        "mu": config.mu,
        "tolerance_ns": config.tolerance_ns,
        "lateness_ns": config.lateness_ns,
        "slice_ns": slice_ns,
        "bags": [str(path) for path in args.bags],
    }
    progress = Progress("dispeval bag", enabled=not args.quiet)
    with ResultsStore.create(args.out, record, resume=args.resume) as store:
        report = evaluate_bags(
            args.bags,
            config,
            store,
            jobs=args.jobs,
            slice_ns=slice_ns,
            progress=lambda done, total, r: progress.update(done, total, r.frames),
        )
        rows = store.export_csv(args.out / "frames.csv")
        summary = summarize(store, args.objective_measures, args.objectives)
        problems = store.problems()
    document = summary.to_dict()
    write_json(args.out / "summary.json", document)
    if args.json:
        print_json(document)
        return 0
    print(
        f"results: {args.out / 'results.sqlite'} ({rows} rows; "
        f"{args.out / 'frames.csv'}, {args.out / 'summary.json'})"
    )
    print(
        f"this run: {report.units_done} units, {report.frames} method-frames, {report.messages} messages read"
    )
    print(run_summary_text(summary, problems))
    return 0
