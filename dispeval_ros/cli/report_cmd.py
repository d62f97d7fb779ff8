"""``dispeval report``: one self-contained, interactive HTML report of a results database."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any, TextIO

from dispeval_ros.cli.common import add_objective_options
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
    objectives = parser.add_argument_group(
        "the A* Groups of the latency view (default: the run's, from RESULTS/summary.json)"
    )
    add_objective_options(objectives, default=None)
    parser.add_argument(
        "--quiet",
        action="store_true",
        help="no progress lines (on a terminal, stderr says what is being done and how long)",
    )
    parser.set_defaults(run=run_command)


def _folder(results: Path) -> Path:
    return results.parent if results.suffix == ".sqlite" or results.is_file() else results


def default_output(results: Path) -> Path:
    """``RESULTS/report.html`` (beside results.sqlite when a file is given)."""
    return _folder(results) / "report.html"


def run_objectives(args: argparse.Namespace) -> tuple[list[str] | None, str]:
    """The objective measures and granularity of the latency view's A* Groups.

    Those given, else the run's (``summary.json`` beside the database: what its A* Groups were
    computed on, ``latency_p95`` included if the run ranked on it), else the default rule.
    """
    from dispeval_ros.io.store import SUMMARY_JSON

    recorded: dict[str, Any] = {}
    try:
        document = json.loads((_folder(args.results) / SUMMARY_JSON).read_text("utf-8"))
        if isinstance(document, dict):
            recorded = document
    except (OSError, ValueError):
        pass  # no summary (or not one of ours): the default rule
    measures = args.objective_measures
    if measures is None and isinstance(recorded.get("objective_measures"), list):
        measures = [str(m) for m in recorded["objective_measures"]]
    granularity = args.objectives or recorded.get("granularity")
    return measures, granularity if isinstance(granularity, str) else "sequence"


class _Steps:
    """Progress lines on a terminal's stderr: what the report is doing and how long it took.

    The slow steps are silent otherwise: scoring frames again for the error maps (the first use
    of the kernels after an install compiles them: about 15 s) and the first matplotlib import
    (it builds its font cache). Not written when stderr is no terminal (a log, a pipe): there a
    refusal stays the one line it is.
    """

    def __init__(self, quiet: bool, stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stderr
        self.quiet = quiet or not self.stream.isatty()
        self.started = time.perf_counter()

    def say(self, text: str) -> None:
        if not self.quiet:
            elapsed = time.perf_counter() - self.started
            print(f"report: [{elapsed:5.1f} s] {text}", file=self.stream, flush=True)


def check_objective_measures(stored: list[str], given: list[str]) -> None:
    """Refuse ``--objective-measures`` naming neither a stored measure nor a timing one.

    Pair and ego-motion residual measures pass: the summary says in one line when they were
    not recorded.
    """
    from dispeval_ros.core.objectives import is_egomotion_measure, is_pair_measure
    from dispeval_ros.core.timing import TIMING_MEASURES

    unknown = [
        m
        for m in given
        if m not in stored
        and m not in TIMING_MEASURES
        and not is_pair_measure(m)
        and not is_egomotion_measure(m)
    ]
    if unknown:
        raise ConfigurationError(
            f"--objective-measures {' '.join(unknown)}: neither stored ({', '.join(stored)}) "
            f"nor a timing measure ({', '.join(TIMING_MEASURES)}), a pair measure (tepe...) or "
            "an ego-motion residual one (egomotion_rms...)"
        )


def run_command(args: argparse.Namespace) -> int:
    """Read the database, make thumbnails and figures if asked, write the HTML."""
    from dispeval_ros.io.store import ResultsStore
    from dispeval_ros.report.data import build_report_data
    from dispeval_ros.report.maps import error_thumbnails, frames_to_show

    if args.thumbnails < 0:
        raise ConfigurationError(f"--thumbnails must be 0 or more, got {args.thumbnails}")
    out = args.out or default_output(args.results)
    steps = _Steps(args.quiet)
    with ResultsStore.open(args.results) as store:
        thumbnails = None
        if args.bag:
            total = frames_to_show(store, args.bag, args.thumbnails)
            steps.say(
                f"error maps: scoring {total} frames again from {len(args.bag)} bag(s) (a first "
                "run after an install compiles the scoring kernels first)"
            )
            thumbnails = error_thumbnails(
                store,
                args.bag,
                args.thumbnails,
                progress=lambda done: steps.say(f"error maps: frame {done}/{total} done"),
            )
            if thumbnails is None and total:
                steps.say(
                    "error maps: none (no frame found again; a run without ground truth has none)"
                )
        steps.say("reading the results database")
        measures, granularity = run_objectives(args)
        if args.objective_measures is not None:
            check_objective_measures(store.measures(), args.objective_measures)
        data = build_report_data(
            store,
            title=args.title,
            thumbnails=thumbnails,
            objective_measures=measures,
            granularity=granularity,
        )
        from dispeval_ros.report.html import write_report

        size = write_report(data, out)  # first: a problem with the figures keeps the page
        print(f"report: {out} ({size / 1e6:.1f} MB)")
        if args.png:
            from dispeval_ros.report.figures import FIGURES, write_figures

            steps.say(
                f"figures: importing matplotlib (its first use builds a font cache) and drawing "
                f"{len(FIGURES)} figures (and the latency ones where arrival times are recorded)"
            )
            written = write_figures(
                store, args.png, latency=data["latency"], temporal=data["temporal"]
            )
            steps.say("figures: done")
            print(f"figures: {', '.join(str(path) for path in written)}")
    return 0
