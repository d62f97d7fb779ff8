"""``dispeval report``: one self-contained, interactive HTML report of a results database."""

from __future__ import annotations

import argparse
from pathlib import Path

from dispeval_ros.errors import ConfigurationError

HELP = "write an interactive HTML report (offline, one file) of a results database"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``report``."""
    parser = subparsers.add_parser(
        "report",
        help=HELP,
        description=HELP + ". Pick sequences and frames, criteria, measures, methods, the "
        "objective granularity and the model in the page; the groups, the reduced set and the "
        "interpretation are recomputed in the browser, exactly as 'dispeval bag' computes them.",
    )
    parser.add_argument(
        "results",
        type=Path,
        metavar="RESULTS",
        help="results folder of 'dispeval bag' or the summarizer, or its results.sqlite",
    )
    parser.add_argument(
        "-o",
        "--out",
        type=Path,
        help="HTML file to write (default: RESULTS/report.html)",
    )
    parser.add_argument(
        "--png", type=Path, metavar="DIR", help="also write static PNG figures to DIR"
    )
    parser.add_argument(
        "--bag",
        action="append",
        type=Path,
        default=[],
        metavar="BAG",
        help="a recorded bag of the results (repeat for every sequence): error-map thumbnails "
        "of a few frames are made from it",
    )
    parser.add_argument(
        "--thumbnails",
        type=int,
        default=4,
        metavar="N",
        help="frames with error-map thumbnails when --bag is given (default 4)",
    )
    parser.add_argument("--title", help="report title (default: from the results folder)")
    parser.set_defaults(run=run_command)


def default_output(results: Path) -> Path:
    """``RESULTS/report.html`` (beside results.sqlite when a file is given)."""
    folder = results.parent if results.suffix == ".sqlite" or results.is_file() else results
    return folder / "report.html"


def run_command(args: argparse.Namespace) -> int:
    """Read the database, make thumbnails and figures if asked, write the HTML."""
    from dispeval_ros.io.store import ResultsStore
    from dispeval_ros.report.data import build_report_data, error_thumbnails
    from dispeval_ros.report.html import write_report

    if args.thumbnails < 0:
        raise ConfigurationError(f"--thumbnails must be 0 or more, got {args.thumbnails}")
    out = args.out or default_output(args.results)
    with ResultsStore.open(args.results) as store:
        thumbnails = error_thumbnails(store, args.bag, args.thumbnails) if args.bag else None
        data = build_report_data(store, title=args.title, thumbnails=thumbnails)
        size = write_report(data, out)  # first: a problem with the figures keeps the page
        print(f"report: {out} ({size / 1e6:.1f} MB)")
        if args.png:
            from dispeval_ros.report.figures import write_figures

            written = write_figures(store, args.png)
            print(f"figures: {', '.join(str(path) for path in written)}")
    return 0
