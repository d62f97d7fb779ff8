"""``dispeval play``: publish a bag's topics on DDS at their recorded rate, like ``ros2 bag play``."""

from __future__ import annotations

import argparse
import math
import sys
import threading
import time
from pathlib import Path

from dispeval_ros.cli.live_cmd import install_stop_handlers, restore_handlers
from dispeval_ros.dds import environment
from dispeval_ros.errors import ConfigurationError

HELP = "publish a bag's topics over DDS with their types and recorded timing (no ROS needed)"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``play``."""
    parser = subparsers.add_parser(
        "play",
        help=HELP,
        description=HELP + ". ROS 2 nodes (rmw_cyclonedds_cpp) and 'dispeval live' on the same "
        "domain receive them. rosbag2 bags are re-published byte for byte; ROS 1 and plain MCAP "
        "messages are converted to the ROS 2 Humble types. Before the first message the player "
        "waits (at most --wait-matched seconds) for subscribers.",
    )
    parser.add_argument("bag", type=Path, metavar="BAG", help="rosbag2 folder, .mcap, .db3 or .bag")
    parser.add_argument("--transport", default="dds", help="'dds' (Cyclone DDS); the only one")
    timing = parser.add_mutually_exclusive_group()
    timing.add_argument(
        "--rate",
        type=float,
        default=1.0,
        help="speed factor of the recorded timing, a finite number > 0 (default 1; not inf: "
        "use --fast)",
    )
    timing.add_argument("--fast", action="store_true", help="as fast as possible")
    parser.add_argument(
        "--topics",
        nargs="+",
        metavar="TOPIC",
        help="only these topics, all in the bag (default: all)",
    )
    parser.add_argument("--loop", action="store_true", help="play again and again until stopped")
    parser.add_argument(
        "--wait-matched",
        type=float,
        default=2.0,
        metavar="S",
        help="wait up to S seconds for subscribers before playing: until every topic has one, "
        "or no new one appeared for 1 s (default 2; 0: do not wait)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    environment.add_arguments(parser)
    parser.set_defaults(run=run_command)


def run_command(args: argparse.Namespace) -> int:
    """Open the bag, create the writers, wait for subscribers, play."""
    if args.transport != "dds":
        raise ConfigurationError(
            f"--transport {args.transport} is not available; use --transport dds "
            "(with ROS 2 installed, use ros2 bag play)"
        )
    from dispeval_ros.dds.player import check_rate, played_topics
    from dispeval_ros.io.bags import BagSource

    rate = None if args.fast else args.rate
    check_rate(rate)
    if not (math.isfinite(args.wait_matched) and args.wait_matched >= 0):
        raise ConfigurationError(
            f"--wait-matched must be a number of seconds ≥ 0, got {args.wait_matched}"
        )
    with BagSource(args.bag) as source:  # a bad path or topic, before the transport is needed
        played_topics(source, args.topics)
    uri = environment.configure(args.dds_config)
    domain = environment.domain_id(args.domain_id)
    environment.require_cyclonedds()

    from dispeval_ros.dds.player import BagPlayer
    from dispeval_ros.dds.transport import DdsTransport

    transport = DdsTransport(domain)
    stop = threading.Event()
    previous = install_stop_handlers(stop)
    try:
        player = BagPlayer(transport, args.bag, args.topics)
        total = sum(t.count for t in player.topics.values())
        how = "as recorded" if player.raw else "converted to ROS 2 Humble types"
        print(
            f"dispeval play: {args.bag}: {len(player.topics)} topic(s), {total} messages "
            f"({how}) on {environment.describe(uri, domain)}",
            file=sys.stderr,
            flush=True,
        )
        if args.wait_matched > 0:
            missing = player.wait_matched(args.wait_matched)
            if missing:
                print(
                    f"dispeval play: no subscriber on {', '.join(missing)}; playing anyway",
                    file=sys.stderr,
                )
            if len(missing) < len(player.writers):
                time.sleep(0.2)  # the subscribers match the writers a moment after
        progress = _Progress(total, enabled=not args.quiet)
        started = time.monotonic()
        try:
            count = player.play(rate=rate, loop=args.loop, stop=stop, on_message=progress.update)
        finally:
            progress.close()
            player.finish()
        elapsed = time.monotonic() - started
        print(
            f"dispeval play: published {count} messages in {elapsed:.1f} s"
            + (" (stopped)" if stop.is_set() else "")
        )
    finally:
        transport.close()
        restore_handlers(previous)
    return 0


class _Progress:
    """``dispeval play: 120/300 messages`` redrawn on a terminal, silent otherwise."""

    def __init__(self, total: int, enabled: bool) -> None:
        self.total = total
        self.enabled = enabled and sys.stderr.isatty()
        self.count = 0
        self._last = 0.0

    def update(self, topic: str, log_ns: int) -> None:
        self.count += 1
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self._last >= 0.2:
            self._last = now
            shown = self.count if self.count <= self.total else f"{self.count} (looping)"
            sys.stderr.write(f"\rdispeval play: {shown}/{self.total} messages")
            sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
