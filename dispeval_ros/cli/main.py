"""The ``dispeval`` command: argument parsing and error reporting only."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from collections.abc import Sequence
from types import FrameType
from typing import NoReturn

from dispeval_ros.cli import (
    bag_cmd,
    demo_cmd,
    eval_cmd,
    info_cmd,
    live_cmd,
    make_bag_cmd,
    make_scene_cmd,
    merge_cmd,
    models_cmd,
    play_cmd,
    report_cmd,  # the interactive HTML report
    tune_cmd,
)
from dispeval_ros.errors import ConfigurationError, DispevalError, ResultsConflictError
from dispeval_ros.version import __version__

COMMANDS = (
    eval_cmd,
    bag_cmd,
    merge_cmd,
    models_cmd,
    info_cmd,
    make_bag_cmd,
    make_scene_cmd,
    demo_cmd,
    live_cmd,
    play_cmd,
    report_cmd,
    tune_cmd,
)


class OneLineParser(argparse.ArgumentParser):
    """argparse, but a usage mistake is one line (naming --help) instead of the usage block."""

    def error(self, message: str) -> NoReturn:
        """Print ``PROG: error: MESSAGE (see PROG --help)`` and exit with status 2."""
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The full parser (one sub-command per module in :data:`COMMANDS`)."""
    parser = OneLineParser(
        prog="dispeval",
        description="Judge stereo methods by their disparity maps: set-partition criteria "
        "(visibility, depth, ROI), SZE/BMPRE and classic measures, Pareto models (A* Groups).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in COMMANDS:
        command.add_parser(subparsers)
    return parser


def cli_advice(conflict: ResultsConflictError) -> ConfigurationError:
    """A results-folder conflict with its remedy in command-line terms."""
    return conflict.advised(
        resume="use --resume to continue them",
        same_options="resume with the same options",
        elsewhere="choose another --out",
    )


class Terminated(KeyboardInterrupt):
    """SIGTERM (timeout, docker, CI): stop as on Ctrl-C, cleanly and resumably."""


def _on_sigterm(signum: int, frame: FrameType | None) -> None:
    raise Terminated


def main(argv: Sequence[str] | None = None) -> int:
    """Run a command; user mistakes print one line and exit with status 2."""
    parser = build_parser()
    args = parser.parse_args(argv)
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        try:
            return int(args.run(args))
        except ResultsConflictError as conflict:
            raise cli_advice(conflict) from None
    except DispevalError as error:
        print(f"dispeval {args.command}: error: {error}", file=sys.stderr)
        return 2
    except Terminated:
        print(f"dispeval {args.command}: terminated (what was stored is kept)", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print(f"dispeval {args.command}: interrupted (what was stored is kept)", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
