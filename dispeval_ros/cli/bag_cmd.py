"""``dispeval bag``: evaluate recorded stereo streams (rosbag2 sqlite3/MCAP, ROS 1, MCAP)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dispeval_ros.cli import protocol_eval, streams
from dispeval_ros.cli.output import plural, print_json, wrapped
from dispeval_ros.cli.progress import Progress
from dispeval_ros.cli.summary import run_summary_text
from dispeval_ros.errors import ConfigurationError

if TYPE_CHECKING:
    from collections.abc import Iterable

    from dispeval_ros.io.bags import BagSource

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
    add_bags_argument(parser)
    run = streams.add_stream_options(parser, egomotion=True)
    run.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    run.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run the units on a Dask cluster: tcp://HOST:PORT of its scheduler (the workers "
        "must see the bag paths), or local:N for a local cluster of N worker processes",
    )
    run.add_argument("--resume", action="store_true", help="continue an interrupted run in --out")
    run.add_argument(
        "--slice",
        default="5",
        metavar="SECONDS|auto",
        help="seconds of bag per unit of work (default 5); auto: from each bag's length and "
        "the number of workers",
    )
    run.add_argument("--quiet", action="store_true", help="no progress line")
    run.add_argument("--json", action="store_true", help="print the summary as JSON")
    protocol_eval.add_stream_option(parser)
    parser.set_defaults(run=run_command)


def add_bags_argument(parser: argparse.ArgumentParser) -> None:
    """The ``BAG...`` positional of the commands that read bags (``bag``, ``info``)."""
    parser.add_argument(
        "bags",
        nargs="+",
        type=Path,
        metavar="BAG",
        help="rosbag2 folder, .mcap, .db3 or ROS 1 .bag",
    )


def slice_option(text: str) -> int | None:
    """``--slice`` in nanoseconds (None for auto); one line when it is not a positive number."""
    if text == "auto":
        return None
    try:
        slice_ns = round(float(text) * 1e9)
    except (ValueError, OverflowError):  # not a number, nan, inf
        slice_ns = 0
    if slice_ns <= 0:
        raise ConfigurationError(
            f"--slice must be a positive number of seconds or auto, got {text}"
        )
    return slice_ns


def check_before_writing(args: argparse.Namespace, config: Any) -> None:
    """Every option, bag and topic is checked before the results folder is created.

    A run refused at start leaves nothing behind, so the corrected command runs as it is.
    """
    from dispeval_ros.offline.executors import check_engine
    from dispeval_ros.offline.units import check_topics, open_bag
    from dispeval_ros.stream.core import CAMERA_INFO_TYPE

    check_engine(args.jobs, args.scheduler)
    for bag in args.bags:
        source = open_bag(bag)
        check_topics(source, config)
        infos = [t for t, i in source.topics.items() if i.msgtype == CAMERA_INFO_TYPE]
        if infos and not config.left_info_topic:
            print(
                f"dispeval bag: warning: {bag} has CameraInfo topics ({', '.join(infos)}) but "
                "--camera-info was not given: the camera comes from each DisparityImage's f and "
                "t, which carry no doffs (SZE and depth measures are wrong if doffs ≠ 0)",
                file=sys.stderr,
            )
        if not config.left_info_topic:
            for warning in _negative_t(source, config.methods.values()):
                print(f"dispeval bag: warning: {bag}: {warning}", file=sys.stderr)


def _negative_t(source: BagSource, topics: Iterable[str]) -> list[str]:
    """The negative-t warning of each topic whose first DisparityImage has ``t < 0``.

    Said once per topic and bag before the run, as the doffs warning; the camera comes from the
    DisparityImages only without ``--camera-info``.
    """
    from dispeval_ros.errors import DispevalError
    from dispeval_ros.io.messages import disparity_from_msg
    from dispeval_ros.stream.core import negative_t_warning

    warnings = []
    for topic in topics:
        try:
            first = next(iter(source.messages([topic])), None)
            frame = None if first is None else disparity_from_msg(first[2], topic)
        except DispevalError:  # the run records what is wrong with it, frame by frame
            continue
        warning = None if frame is None else negative_t_warning(frame, topic)
        if warning is not None:
            warnings.append(warning)
    return warnings


def camera_text(config: Any) -> str:
    """Which camera the depth measures used (printed with the summary)."""
    if config.left_info_topic:
        return f"camera: from CameraInfo {config.left_info_topic} and {config.right_info_topic}"
    return "camera: from each DisparityImage's f and t (no doffs)"


def run_command(args: argparse.Namespace) -> int:
    """Evaluate, export, summarise."""
    from dispeval_ros.io.store import ResultsStore
    from dispeval_ros.offline.bag_eval import evaluate_bags, recorded_bags
    from dispeval_ros.offline.executors import ready_executor
    from dispeval_ros.offline.records import BagStreams, record_bag_provenance, write_run_files

    preset = protocol_eval.apply_stream_preset(args)
    config = streams.core_config(args, "bags")
    slice_ns = slice_option(args.slice)
    check_before_writing(args, config)
    record = {
        **config.as_record(),
        "slice_ns": "auto" if slice_ns is None else slice_ns,
        "bags": recorded_bags(args.out, args.bags, args.resume),
        **preset,
    }
    progress = Progress("dispeval bag", enabled=not args.quiet)
    digests = BagStreams(args.bags, config)  # hashed while the units run
    with (
        ready_executor(config, args.jobs, args.scheduler, args.bags) as engine,
        ResultsStore.create(args.out, record, resume=args.resume) as store,
    ):
        report = evaluate_bags(
            args.bags,
            config,
            store,
            executor=engine,
            slice_ns=slice_ns,
            progress=lambda done, total, r: progress.update(done, total, r.frames),
            alongside=digests.compute,
            warn=lambda text: print(f"dispeval bag: warning: {text}", file=sys.stderr),
        )
        provenance = record_bag_provenance(store, args.bags, record, config, digests)
        files = write_run_files(
            store, args.out, provenance, args.objective_measures, args.objectives
        )
        problems = store.problems()
    rows, summary = files.rows, files.summary
    if args.json:
        print_json(files.document)
        return 0
    print(
        wrapped(
            f"results: {args.out / 'results.sqlite'} ({rows} rows; "
            f"{args.out / 'frames.csv'}, {args.out / 'summary.json'})"
        )
    )
    print(
        f"this run: {plural(report.units_done, 'unit')}, {plural(report.frames, 'method-frame')}"
        f", {plural(report.messages, 'message')} read"
        + (f", {report.retries} unit(s) retried" if report.retries else "")
        + (
            f", {report.failed_before} unit(s) that had failed before tried again"
            if report.failed_before
            else ""
        )
    )
    if preset:
        print(protocol_eval.preset_note(args.protocol))
    print(camera_text(config))
    print(run_summary_text(summary, problems))
    return 0
