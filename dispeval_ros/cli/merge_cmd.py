"""``dispeval merge``: one results folder from several runs (e.g. one per machine)."""

from __future__ import annotations

import argparse
from pathlib import Path

from dispeval_ros.cli.common import add_objective_options
from dispeval_ros.cli.output import print_json

HELP = "merge results databases made separately (same configuration) into one"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``merge``."""
    parser = subparsers.add_parser(
        "merge",
        help=HELP,
        description=HELP + ", so that summaries and reports cover all their sequences. Units "
        "are copied in the order given; a unit stored in two of them is refused. OUT gets the "
        "results.sqlite, frames.csv and summary.json of one 'dispeval bag' run over all the "
        "bags, written only when the whole merge succeeds.",
    )
    parser.add_argument("out", type=Path, metavar="OUT", help="new results folder")
    parser.add_argument(
        "results", nargs="+", type=Path, metavar="RESULTS", help="results folders or files"
    )
    add_objective_options(parser)
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    parser.set_defaults(run=run_command)


def run_command(args: argparse.Namespace) -> int:
    """Merge and say what was written."""
    from dispeval_ros.io.store import FRAMES_CSV, SUMMARY_JSON
    from dispeval_ros.offline.merge import merge_results

    report = merge_results(args.out, args.results, args.objective_measures, args.objectives)
    if args.json:
        print_json(report.files.document)
        return 0
    print(
        f"merged {report.runs} results into {report.path}: {report.sequences} sequences, "
        f"{report.units} units ({report.files.rows} rows; {args.out / FRAMES_CSV}, "
        f"{args.out / SUMMARY_JSON})"
    )
    return 0
