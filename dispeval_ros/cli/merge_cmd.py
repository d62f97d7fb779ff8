"""``dispeval merge``: one results database from several runs (e.g. one per machine)."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "merge results databases made separately (same configuration) into one"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``merge``."""
    parser = subparsers.add_parser(
        "merge",
        help=HELP,
        description=HELP + ", so that summaries and reports cover all their sequences. Units "
        "are copied in the order given; a unit stored in two of them is refused.",
    )
    parser.add_argument("out", type=Path, metavar="OUT", help="new results folder")
    parser.add_argument(
        "results", nargs="+", type=Path, metavar="RESULTS", help="results folders or files"
    )
    parser.set_defaults(run=run_command)


def run_command(args: argparse.Namespace) -> int:
    """Merge and say what was written."""
    from dispeval_ros.offline.merge import merge_results

    report = merge_results(args.out, args.results)
    print(
        f"merged {report.runs} results into {report.path}: {report.sequences} sequences, "
        f"{report.units} units"
    )
    return 0
