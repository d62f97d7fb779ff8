"""``dispeval models``: A*, A* Groups, front reduction and Middlebury ranks.

Of a scores CSV (a ``method`` column, one column per objective), or of the results of
``dispeval bag`` / ``live`` / the summarizer (a results folder, its ``results.sqlite`` or its
``frames.csv``), whose objectives are built from the stored sums exactly as their summary
builds them, and can be exported as such a CSV.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dispeval_ros.cli.common import add_objective_options
from dispeval_ros.cli.output import print_json, table
from dispeval_ros.cli.summary import models_text
from dispeval_ros.core import astar_groups, evaluate_models, measure_consistency
from dispeval_ros.errors import ConfigurationError, InputError

HELP = "compare methods by Pareto dominance over the objectives of a scores CSV or of results"
MODELS = ("groups", "astar", "middlebury")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``models``."""
    parser = subparsers.add_parser(
        "models",
        help=HELP,
        description=HELP + ". A scores CSV has a 'method' column and one column per objective; "
        "lower is better in every column. Results (a folder of 'dispeval bag', its "
        "results.sqlite or frames.csv) give objectives per (criterion, sequence) or "
        "(criterion, frame) of the chosen measures, from the stored sums.",
    )
    parser.add_argument("scores", type=Path, metavar="SCORES.csv|RESULTS")
    add_objective_options(parser)
    parser.add_argument(
        "--export",
        type=Path,
        metavar="FILE.csv",
        help="also write the objectives compared as a scores CSV (method + one column each)",
    )
    parser.add_argument(
        "--model",
        choices=MODELS,
        default="groups",
        help="groups: A* Groups with the front reduction (default); astar: the first front only; "
        "middlebury: average ranks",
    )
    parser.add_argument(
        "--consistency",
        nargs=2,
        metavar=("MEASURE_A", "MEASURE_B"),
        help="share of method pairs whose A* Groups relation agrees between the columns ending in "
        "/MEASURE_A and those ending in /MEASURE_B (e.g. sze bmp)",
    )
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.set_defaults(run=run)


def _consistency(
    path: Path, measures: list[str], objectives: list[str], matrix: np.ndarray
) -> float:
    groups = []
    for measure in measures:
        columns = [
            i
            for i, name in enumerate(objectives)
            if name == measure or name.endswith("/" + measure)
        ]
        if not columns:
            raise ConfigurationError(
                f"{path}: no column is named '{measure}' or ends with '/{measure}'"
            )
        groups.append(astar_groups(matrix[:, columns]))
    return measure_consistency(groups[0], groups[1])


def read_table(
    path: Path, measures: list[str] | None, granularity: str
) -> tuple[list[str], list[str], np.ndarray]:
    """Methods, objectives and matrix of a scores CSV or of stored results.

    ``measures`` None: the default objectives of the measures stored.
    """
    from dispeval_ros.io.store import RESULTS_FILE, ResultsStore
    from dispeval_ros.io.tables import is_frames_csv, read_objectives_csv
    from dispeval_ros.summary import objective_table

    results = None
    if path.is_dir() or path.suffix == ".sqlite":
        results = path
    elif is_frames_csv(path):
        results = path.parent / RESULTS_FILE
        if not results.is_file():
            raise InputError(
                f"{path} holds per-frame values of 'dispeval bag' results but no {RESULTS_FILE} "
                "is beside it: give the results folder, whose sums make exact objectives"
            )
    if results is None:
        return read_objectives_csv(path)
    with ResultsStore.open(results) as store:
        methods, objectives, matrix = objective_table(store, measures, granularity)
    if not objectives:
        raise InputError(
            f"{results}: no objectives: fewer than two methods, or no frame every method delivered"
        )
    return methods, objectives, matrix


def run(args: argparse.Namespace) -> int:
    """Read the table, run the models, print."""
    from dispeval_ros.io.tables import write_objectives_csv

    methods, objectives, matrix = read_table(args.scores, args.objective_measures, args.objectives)
    if args.export:
        try:
            write_objectives_csv(args.export, methods, objectives, matrix)
        except OSError as error:
            raise InputError(f"{args.export}: cannot write ({error.strerror or error})") from None
    try:
        result = evaluate_models(methods, matrix)
    except ConfigurationError as error:
        raise ConfigurationError(f"{args.scores}: {error}") from None
    consistency = None
    if args.consistency:
        consistency = _consistency(args.scores, list(args.consistency), objectives, matrix)
    if args.json:
        document = result.to_dict()
        if consistency is not None:
            document["consistency"] = {"measures": list(args.consistency), "share": consistency}
        print_json(document)
        return 0
    if args.model == "groups":
        print(models_text(result, objectives))
    elif args.model == "astar":
        print(f"A* ({len(result.astar)} of {len(methods)} methods): {', '.join(result.astar)}")
        print(result.interpretation.splitlines()[0])
    else:
        order = sorted(methods, key=lambda m: result.middlebury[m])
        print(table(["method", "avg rank"], [[m, result.middlebury[m]] for m in order]))
    if consistency is not None:
        a, b = args.consistency
        print(f"\nmeasure consistency {a} vs {b}: {consistency:.4f} of method pairs agree")
    return 0
