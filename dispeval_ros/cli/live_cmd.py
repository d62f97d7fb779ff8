"""``dispeval live``: evaluate a robot's live stereo streams over DDS, without ROS."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from pathlib import Path
from types import FrameType
from typing import Any

from dispeval_ros.cli import streams
from dispeval_ros.cli.summary import run_summary_text
from dispeval_ros.dds import environment
from dispeval_ros.errors import ConfigurationError, InputError, ResultsConflictError
from dispeval_ros.stream.config import QUEUE_SIZE, field_default
from dispeval_ros.stream.summarizer import SummarizerConfig
from dispeval_ros.stream.topics import GROUPS_TOPIC, SCORES_TOPIC, VECTOR_LEAF, method_topic

HELP = "evaluate live stereo streams (ROS 2 topics over Cyclone DDS, no ROS needed)"
TRANSPORTS = ("dds",)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``live``."""
    every_n = field_default(SummarizerConfig, "every_n")
    parser = subparsers.add_parser(
        "live",
        help=HELP,
        description=HELP + ". Subscribes to the ground truth and every method's DisparityImage "
        "(best-effort, as sensor data), scores each frame joined by stamp, publishes "
        f"{SCORES_TOPIC} (DiagnosticArray), {method_topic('<method>', VECTOR_LEAF)} "
        f"(Float64MultiArray) and {GROUPS_TOPIC}, and writes the same results.sqlite, frames.csv "
        "and summary.json as 'dispeval bag' into --out. Ctrl-C (SIGINT) or SIGTERM stops cleanly.",
    )
    parser.add_argument(
        "--transport",
        default="dds",
        help="'dds' (Cyclone DDS, interoperates with rmw_cyclonedds_cpp); the only one for now",
    )
    run = streams.add_stream_options(parser, egomotion=True)
    alarms = parser.add_argument_group("alarms (levels of the published statuses)")
    alarms.add_argument("--warn", nargs="+", default=[], metavar="C/M=V", help="e.g. all/bmp=20")
    alarms.add_argument("--error", nargs="+", default=[], metavar="C/M=V", help="e.g. all/bmp=40")
    run.add_argument(
        "--resume", action="store_true", help="add to the results in --out (as new sequences)"
    )
    run.add_argument(
        "--summary-every",
        type=int,
        default=every_n,
        metavar="N",
        help=f"write frames and recompute the groups every N frames (default {every_n}); the period "
        "grows when a summary would take more than a tenth of the time (long runs)",
    )
    run.add_argument(
        "--queue-size",
        type=int,
        default=QUEUE_SIZE,
        metavar="N",
        help=f"joined frames waiting for scoring before the oldest is dropped (default {QUEUE_SIZE})",
    )
    run.add_argument(
        "--duration", type=float, default=None, metavar="S", help="stop after S seconds"
    )
    run.add_argument("--quiet", action="store_true", help="no live line")
    temporal = next(g for g in parser._action_groups if g.title == "temporal")
    temporal.add_argument(
        "--odometry",
        metavar="TOPIC",
        help="with --egomotion: a nav_msgs/Odometry topic whose pose (header.frame_id → "
        "child_frame_id) moves the camera, read instead of /tf (a robot that publishes "
        "odometry only)",
    )
    temporal.add_argument(
        "--camera-mount",
        type=Path,
        metavar="FILE",
        help="with --odometry: the odometry's child frame → left optical frame, a file of 16 "
        "numbers (4×4) or 7 (x y z qx qy qz qw) as --extrinsic; default: from /tf_static (or "
        "the child frame is the camera's)",
    )
    environment.add_arguments(parser)
    parser.set_defaults(run=run_command)


def run_command(args: argparse.Namespace) -> int:
    """Check the options, evaluate until stopped, finish the results, print the summary."""
    if args.transport not in TRANSPORTS:
        raise ConfigurationError(
            f"--transport {args.transport} is not available; use --transport dds "
            "(in a ROS 2 workspace, run dispeval's rclpy nodes with ros2 run instead)"
        )
    if args.duration is not None and not args.duration > 0:
        raise ConfigurationError(f"--duration must be positive, got {args.duration}")
    if args.queue_size < 1:
        raise ConfigurationError(f"--queue-size must be at least 1, got {args.queue_size}")
    config = streams.core_config(args, "live streams")  # also checks the objective measures
    from dispeval_ros.stream.config import refuse_live_confidences

    refuse_live_confidences(config, streams.field_names(args.gt_cloud is not None))
    mount = odometry_mount(args)

    from dispeval_ros.dds.evaluator import warm_up
    from dispeval_ros.dds.session import LiveSession
    from dispeval_ros.dds.wire import vector_topic
    from dispeval_ros.stream.alarms import AlarmThresholds
    from dispeval_ros.stream.summarizer import SummarizerConfig
    from dispeval_ros.stream.topics import GROUPS_TOPIC, SCORES_TOPIC

    for method in config.methods:
        vector_topic(method)
    alarms = AlarmThresholds.parse(args.warn, args.error, config.scored_measures)
    summary_config = SummarizerConfig(
        args.out, args.objective_measures, args.objectives, args.summary_every, args.resume
    )
    record = live_record(config)
    check_out(args.out, args.resume, record)
    uri = environment.configure(args.dds_config)
    domain = environment.domain_id(args.domain_id)
    environment.require_cyclonedds()
    warm_up(config)
    session = LiveSession(
        domain,
        config,
        summary_config,
        record,
        alarms=alarms,
        queue_size=args.queue_size,
        on_error=_warn,
        odometry=args.odometry,
        mount=mount,
    )
    stop = threading.Event()
    previous = install_stop_handlers(stop)
    try:
        session.start()
        print(
            f"dispeval live: listening on {environment.describe(uri, domain)}: "
            f"{len(config.methods)} method(s) against {config.gt_topic}; publishing "
            f"{SCORES_TOPIC}, {GROUPS_TOPIC}; results in {args.out} (Ctrl-C to stop)",
            file=sys.stderr,
            flush=True,
        )
        _run_until_stopped(session, stop, args.duration, quiet=args.quiet)
        print("dispeval live: stopping: scoring what arrived, writing results…", file=sys.stderr)
        summary = session.stop()
    finally:
        session.stop()
        restore_handlers(previous)
    return _report(session, summary, args.out)


def odometry_mount(args: argparse.Namespace) -> Any:
    """``--odometry`` and ``--camera-mount`` checked (each needs the one before); the mount."""
    if args.odometry is not None and not args.egomotion:
        raise ConfigurationError("--odometry moves the camera for --egomotion: give it too")
    if args.camera_mount is None:
        return None
    if args.odometry is None:
        raise ConfigurationError(
            "--camera-mount mounts the camera on the odometry's child frame: give --odometry "
            "too (with /tf, the mount comes from /tf_static)"
        )
    from dispeval_ros.io.lidar import read_extrinsic

    return read_extrinsic(args.camera_mount)


def live_record(config: Any) -> dict[str, object]:
    """The run record of a ``live`` run (what ``--resume`` must find again)."""
    return {"source": "dispeval live (DDS)", **config.as_record()}


def check_out(out: Path, resume: bool, record: dict[str, object]) -> None:
    """``--out`` can take this run's results: refused now, not once the transport is up.

    Results there need ``--resume``, and with it the same configuration (``record``).
    """
    from dispeval_ros.io.store import RESULTS_FILE, ResultsStore

    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} is a file; expected a results folder")
    path = out / RESULTS_FILE
    if not path.is_file() or path.stat().st_size == 0:
        return
    with ResultsStore.open(path) as store:  # a damaged or foreign file is one line here too
        if not store.holds_units():
            return
        if not resume:
            raise ResultsConflictError(f"{out} already holds results", resumable=True)
        store.check_resumable(record)


def _warn(message: str) -> None:
    print(f"dispeval live: {message}", file=sys.stderr, flush=True)


def install_stop_handlers(stop: threading.Event) -> dict[int, Any]:
    """SIGINT and SIGTERM set ``stop`` (a clean end); a second SIGINT interrupts at once."""
    if threading.current_thread() is not threading.main_thread():
        return {}

    def handler(signum: int, frame: FrameType | None) -> None:
        if stop.is_set() and signum == signal.SIGINT:
            raise KeyboardInterrupt
        stop.set()

    return {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}


def restore_handlers(previous: dict[int, Any]) -> None:
    """Put back the handlers :func:`install_stop_handlers` replaced."""
    for sig, handler in previous.items():
        signal.signal(sig, handler)


CONNECT_POLL = 0.1
"""Seconds between checks for the input publishers until all are there."""


def _run_until_stopped(
    session: Any, stop: threading.Event, duration: float | None, *, quiet: bool
) -> None:
    """Wait for a signal or the duration, drawing the live line (frames/s) meanwhile.

    Says once when every input topic has a publisher (the robot is seen), quiet or not.
    """
    started = last_time = time.monotonic()
    last_frames = 0
    tty = sys.stderr.isatty()
    period = 1.0 if tty else 10.0
    next_line = started + period
    connected = False
    while True:
        now = time.monotonic()
        end = None if duration is None else started + duration
        if end is not None and now >= end:
            break
        timeout = next_line - now if end is None else min(next_line, end) - now
        if stop.wait(max(0.0, timeout if connected else min(timeout, CONNECT_POLL))):
            break
        if not connected and not session.status().silent:
            connected = True
            print("dispeval live: every input topic has a publisher", file=sys.stderr, flush=True)
        now = time.monotonic()
        if now < next_line:
            continue
        next_line = now + period
        if quiet:
            continue
        status = session.status()
        rate = (status.frames - last_frames) / max(now - last_time, 1e-9)
        last_frames, last_time = status.frames, now
        text = (
            f"dispeval live: {status.frames} frames  {rate:.1f} frames/s  "
            f"{status.messages} messages  dropped {status.dropped} (queue {status.queue_drops})  "
            f"{status.sequence}"
        )
        if status.silent:
            text += f"  no publisher on {', '.join(status.silent)}"
        if tty:
            sys.stderr.write("\r" + text + "   ")
        else:
            sys.stderr.write(text + "\n")
        sys.stderr.flush()
    if tty and not quiet:
        sys.stderr.write("\n")


def _report(session: Any, summary: Any, out: Path) -> int:
    from dispeval_ros.io.store import ResultsStore

    status = session.status()
    print(
        f"this run: {status.frames} frames scored and published, {status.stored} stored, "
        f"{status.messages} messages received, {status.queue_drops} frame(s) dropped by a full "
        f"queue" + (f", {status.restarts} stream restart(s)" if status.restarts else "")
    )
    if not session.complete:
        print(
            "dispeval live: warning: the summarizer did not get every published frame in time",
            file=sys.stderr,
        )
    if summary is None:
        print(f"no frame was scored; {out} holds no frames")
        return 0
    with ResultsStore.open(out) as store:
        problems = store.problems()
    print(f"results: {out / 'results.sqlite'} ({out / 'frames.csv'}, {out / 'summary.json'})")
    print(run_summary_text(summary, problems))
    return 0
