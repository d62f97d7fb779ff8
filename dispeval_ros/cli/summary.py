"""Human-readable scores and model results (shared by eval, demo and later commands)."""

from __future__ import annotations

import shutil
from collections.abc import Mapping, Sequence
from typing import Any

from dispeval_ros.cli.output import table
from dispeval_ros.core import ModelResult
from dispeval_ros.core.measures import GT_FREE_PREFIX, applies, measure_unit

ScoreTable = Mapping[str, Mapping[str, float]]
GT_FREE_LABEL = "  (ground-truth-free: from the left and right images, no GT)"


def measure_header(name: str, relative: bool = False) -> str:
    """A measure's column header with its unit: ``sze [m]``, ``bmp [%]``."""
    unit = measure_unit(name, relative)
    return f"{name} [{unit}]" if unit else name


def fitted_tables(
    header: Sequence[str], rows: Sequence[Sequence[object]], keep: int, width: int | None = None
) -> str:
    """``table``, split by columns into several tables no wider than the terminal.

    The first ``keep`` columns (method, n) are repeated in every part.
    """
    limit = width or max(80, shutil.get_terminal_size((100, 24)).columns)
    parts: list[str] = []
    start = keep
    while start < len(header) or not parts:
        end = start + 1
        while end < len(header):
            columns = [*range(keep), *range(start, end + 1)]
            text = table([header[i] for i in columns], [[r[i] for i in columns] for r in rows])
            if max(len(line) for line in text.splitlines()) > limit:
                break
            end += 1
        columns = [*range(keep), *range(start, min(end, len(header)))]
        parts.append(table([header[i] for i in columns], [[r[i] for i in columns] for r in rows]))
        start = end
    return "\n\n".join(parts)


def scores_text(
    scores: Mapping[str, ScoreTable],
    measures: Sequence[str],
    overlapping: Sequence[str] = (),
    relative: bool = False,
) -> str:
    """One table per criterion (split to the terminal's width): a row per method.

    A criterion shows the measures defined on it: ground-truth-free criteria (``gtfree:``)
    the GT-free measures and density, the others the GT measures.
    """
    blocks = []
    methods = list(scores)
    criteria = list(scores[methods[0]]) if methods else []
    for criterion in criteria:
        shown = [m for m in measures if applies(m, criterion)]
        header = ["method", "n", *(measure_header(m, relative) for m in shown)]
        rows = []
        for method in methods:
            values = scores[method][criterion]
            rows.append([method, int(values["n"]), *(values[m] for m in shown)])
        title = f"criterion: {criterion}"
        if criterion in overlapping:
            title += "  (legacy Middlebury criterion: overlaps the others)"
        if criterion.startswith(GT_FREE_PREFIX):
            title += GT_FREE_LABEL
        blocks.append(title + "\n" + fitted_tables(header, rows, keep=2))
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


SEQUENCE_MEASURES = ("density", "bmp", "mae", "d1", "sze", "sze_mean", "bmpre", "vpe", "lrc")
"""Shown per sequence: SZE is a sum (its size grows with the points); sze_mean is per point."""


def run_summary_text(summary: Any, problems: Sequence[Any] = ()) -> str:
    """Per-sequence counts, scores over the common frames and models; then all sequences."""
    parts = []
    for sequence in summary.sequences:
        parts.append(
            f"\n=== sequence {sequence.sequence}: {sequence.common_frames} frames with every method"
        )
        parts.append(
            table(
                ["method", "matched", "unmatched", "dropped", "failed"],
                [
                    [m, c.matched, c.unmatched, c.dropped, c.failed]
                    for m, c in sequence.counts.items()
                ],
            )
        )
        if sequence.scores:
            first = next(iter(sequence.scores.values()))
            measures = [m for m in SEQUENCE_MEASURES if m == "density" or m in first.measures]
            for criterion in first.criteria:
                shown = [m for m in measures if applies(m, criterion)]
                header = ["method", "n", *(measure_header(m, first.relative) for m in shown)]
                rows = [
                    [m, int(s[criterion]["n"]), *(s[criterion][x] for x in shown)]
                    for m, s in sequence.scores.items()
                ]
                parts.append(
                    f"\ncriterion: {criterion} (summed over the common frames)"
                    + (GT_FREE_LABEL if criterion.startswith(GT_FREE_PREFIX) else "")
                )
                parts.append(fitted_tables(header, rows, keep=2))
        if sequence.models is not None:
            parts.append("\n" + models_text(sequence.models, sequence.objectives))
    if summary.overall is not None:
        parts.append(f"\n=== all {len(summary.sequences)} sequences")
        parts.append(models_text(summary.overall, summary.overall_objectives))
    if problems:
        parts.append(
            f"\n{len(problems)} problem(s) recorded (table 'problems'); first: {problems[0].message}"
        )
    return "\n".join(parts)
