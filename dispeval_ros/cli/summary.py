"""Human-readable scores and model results (shared by eval, demo and later commands)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from dispeval_ros.cli.output import table
from dispeval_ros.core import ModelResult

ScoreTable = Mapping[str, Mapping[str, float]]


def scores_text(
    scores: Mapping[str, ScoreTable], measures: Sequence[str], overlapping: Sequence[str] = ()
) -> str:
    """One table per criterion: a row per method, a column per measure."""
    blocks = []
    methods = list(scores)
    criteria = list(scores[methods[0]]) if methods else []
    for criterion in criteria:
        rows = []
        for method in methods:
            values = scores[method][criterion]
            rows.append([method, values["n"], *(values[m] for m in measures)])
        title = f"criterion: {criterion}"
        if criterion in overlapping:
            title += "  (legacy Middlebury criterion: overlaps the others)"
        blocks.append(title + "\n" + table(["method", "n", *measures], rows))
    return "\n\n".join(blocks)


def models_text(result: ModelResult, objectives: Sequence[str]) -> str:
    """Groups, front reduction and Middlebury ranks as a table, then the interpretation."""
    rows = []
    for method in sorted(result.methods, key=lambda m: (result.groups[m], result.middlebury[m])):
        reduction = result.reduction.get(method)
        rows.append(
            [
                method,
                result.groups[method],
                reduction["u1"] if reduction else "",
                reduction["u2"] if reduction else "",
                "yes" if method in result.reduced else "",
                result.middlebury[method],
            ]
        )
    header = ["method", "A* group", "u1", "u2", "reduced", "avg rank"]
    shown = ", ".join(objectives[:6]) + (
        f", … ({len(objectives)} in all)" if len(objectives) > 6 else ""
    )
    return (
        f"A* Groups over {len(objectives)} objectives ({shown}), all minimised\n"
        + table(header, rows)
        + "\n\n"
        + result.interpretation
    )
