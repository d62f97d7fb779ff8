"""What a parameter sweep looks like: sensitivities, parallel coordinates, density fronts.

The input is one :class:`SweepPoint` per configuration (its parameter values, its measures,
its A* group), as ``dispeval tune`` has them; nothing here reads a database. The sensitivity
of a measure to a parameter is, for every value the parameter takes, the median and the
quartiles of the measure over the configurations with that value (the other parameters vary
across them), and its span: the largest minus the smallest of those medians, the measure's
change the parameter alone accounts for. The parallel coordinates put the swept parameters
beside the measures, A* group 1 in front. Where the density is among the measures, the
density–error front of each error measure (Kostliva & Šára: a threshold swept, each
configuration an operating point) shows what density costs. Figures are matplotlib ``Figure`` objects (no
pyplot).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dispeval_ros.errors import ConfigurationError, InputError
from dispeval_ros.report.canvas import LINE_COLOURS, figure_context, new_figure, plain_numbers

SENSITIVITY_PREFIX = "sensitivity_"
"""``sensitivity_<parameter>.png``: one figure per swept parameter."""
PARALLEL_FIGURE = "sweep_parallel.png"
DENSITY_FIGURE = "density_front.png"
"""The density–error fronts (Kostliva & Šára), where ``density`` is among the measures."""
FRONT_COLOUR, REST_COLOUR = "#1a9850", "#b0b0b0"
MAX_TICKS = 12
"""Up to this many values, a sensitivity figure marks each of them on its axis."""


@dataclass(frozen=True)
class SweepPoint:
    """One configuration of a sweep: its name, parameter values, measures and A* group."""

    name: str
    values: Mapping[str, float]
    measures: Mapping[str, float]
    group: int


@dataclass(frozen=True)
class Sensitivity:
    """One measure against one parameter: per value, the median and quartiles, and the span."""

    parameter: str
    measure: str
    levels: tuple[float, ...]
    median: tuple[float, ...]
    low: tuple[float, ...]
    """First quartiles (NaN where no configuration of that value has a finite measure)."""
    high: tuple[float, ...]
    span: float
    """Largest minus smallest median (NaN with fewer than two finite medians)."""


def swept_parameters(points: Sequence[SweepPoint]) -> list[str]:
    """The parameters that take more than one value in the sweep, in the points' order."""
    names = list(points[0].values) if points else []
    return [n for n in names if len({float(p.values[n]) for p in points}) > 1]


def sensitivities(points: Sequence[SweepPoint]) -> list[Sensitivity]:
    """Every (swept parameter, measure) pair's sensitivity."""
    if not points:
        raise ConfigurationError("a sweep with no configuration has no sensitivity")
    measures = list(points[0].measures)
    out = []
    for parameter in swept_parameters(points):
        values = np.array([float(p.values[parameter]) for p in points])
        levels = np.unique(values)
        for measure in measures:
            scored = np.array([float(p.measures[measure]) for p in points])
            stats = []
            for level in levels:
                chosen = scored[(values == level) & np.isfinite(scored)]
                stats.append(
                    tuple(np.percentile(chosen, (50, 25, 75))) if chosen.size else (math.nan,) * 3
                )
            median, low, high = (tuple(float(s[k]) for s in stats) for k in range(3))
            finite = [m for m in median if math.isfinite(m)]
            span = max(finite) - min(finite) if len(finite) > 1 else math.nan
            out.append(
                Sensitivity(parameter, measure, tuple(levels.tolist()), median, low, high, span)
            )
    return out


def sensitivity_figure(parameter: str, rows: Sequence[Sensitivity], path: Path | None) -> Any:
    """One parameter: a panel per measure, the median (line) and quartiles (band) per value."""
    figure = new_figure(3.2 * len(rows), 2.8)
    panels = figure.subplots(1, len(rows), squeeze=False)[0]
    for k, (axes, row) in enumerate(zip(panels, rows, strict=True)):
        colour = LINE_COLOURS[k % len(LINE_COLOURS)]
        axes.fill_between(row.levels, row.low, row.high, color=colour, alpha=0.2, linewidth=0)
        axes.plot(row.levels, row.median, marker="o", color=colour)
        if len(row.levels) <= MAX_TICKS:  # the values the parameter took, as they are
            axes.set_xticks(row.levels, [f"{v:g}" for v in row.levels])
        axes.set_xlabel(parameter)
        axes.set_title(f"{row.measure} (span {row.span:.3g})", fontsize=9, loc="left")
        plain_numbers(axes)
        axes.grid(True, alpha=0.3)
    if path is not None:
        figure.savefig(path)
    return figure


def parallel_figure(points: Sequence[SweepPoint], path: Path | None) -> Any:
    """Every configuration as a line over the swept parameters and the measures.

    Each axis is scaled to its range (written at its ends); A* group 1 is drawn last, in
    colour, the others grey.
    """
    parameters = swept_parameters(points)
    measures = list(points[0].measures) if points else []
    axes_names = [*parameters, *measures]
    table = np.array(
        [[float(p.values[n]) for n in parameters] + [float(p.measures[m]) for m in measures]
         for p in points]
    )  # fmt: skip
    lows, highs = np.nanmin(table, axis=0), np.nanmax(table, axis=0)
    scaled = (table - lows) / np.where(highs > lows, highs - lows, 1.0)
    figure = new_figure(max(4.0, 1.1 * len(axes_names)), 3.6)
    axes = figure.subplots()
    columns = np.arange(len(axes_names))
    for front in (False, True):
        for point, line in zip(points, scaled, strict=True):
            if (point.group == 1) == front:
                axes.plot(columns, line, color=FRONT_COLOUR if front else REST_COLOUR,
                          linewidth=1.4 if front else 0.6, alpha=0.9 if front else 0.5)  # fmt: skip
    axes.set_xticks(columns, axes_names, rotation=30, ha="right", fontsize=8)
    axes.set_yticks([])
    for column in columns:  # each axis with its own range at its ends
        axes.axvline(column, color="#404040", linewidth=0.5)
        for end, value in ((0.0, lows[column]), (1.0, highs[column])):
            axes.annotate(f"{value:.3g}", (column, end), textcoords="offset points",
                          xytext=(0, -10 if end == 0.0 else 4), ha="center", fontsize=7)  # fmt: skip
    axes.set_ylim(-0.1, 1.12)
    axes.set_title(
        f"{len(points)} configurations; A* group 1 in colour ({sum(p.group == 1 for p in points)})",
        fontsize=9,
        loc="left",
    )
    if path is not None:
        figure.savefig(path)
    return figure


def _criterion(key: str) -> tuple[str, str]:
    """``("bad_2", "all")`` of a sweep measure key ``"bad_2 (all)"``."""
    measure, _, criterion = key.partition(" (")
    return measure, criterion.rstrip(")")


def density_pairs(points: Sequence[SweepPoint]) -> list[tuple[str, str]]:
    """(error key, density key) of every measure shown beside the density of its criterion."""
    keys = list(points[0].measures) if points else []
    pairs = []
    for key in keys:
        measure, criterion = _criterion(key)
        density = f"density ({criterion})"
        if measure != "density" and density in keys:
            pairs.append((key, density))
    return pairs


def density_front(points: Sequence[SweepPoint], error: str, density: str) -> list[SweepPoint]:
    """The configurations no other beats on both density (higher) and ``error`` (lower).

    The density–error front of a threshold sweep: each point is an operating point, the front
    the best error each density can have. Densest first; points with a NaN left out.
    """
    finite = [p for p in points if math.isfinite(p.measures[error] + p.measures[density])]
    finite.sort(key=lambda p: (-p.measures[density], p.measures[error]))
    front: list[SweepPoint] = []
    for point in finite:
        if not front or point.measures[error] < front[-1].measures[error]:
            front.append(point)
    return front


def density_figure(points: Sequence[SweepPoint], path: Path | None) -> Any:
    """Per error measure, every configuration at its (density, error), the front joined."""
    pairs = density_pairs(points)
    figure = new_figure(3.4 * len(pairs), 3.0)
    panels = figure.subplots(1, len(pairs), squeeze=False)[0]
    for axes, (error, density) in zip(panels, pairs, strict=True):
        xs = [p.measures[density] for p in points]
        ys = [p.measures[error] for p in points]
        axes.scatter(xs, ys, s=12, color=REST_COLOUR, zorder=2)
        front = density_front(points, error, density)
        axes.plot([p.measures[density] for p in front], [p.measures[error] for p in front],
                  marker="o", color=FRONT_COLOUR, zorder=3, drawstyle="steps-post")  # fmt: skip
        if len(front) <= MAX_TICKS:
            for point in front:
                axes.annotate(point.name, (point.measures[density], point.measures[error]),
                              textcoords="offset points", xytext=(3, 3), fontsize=6)  # fmt: skip
        axes.set_xlabel(density)
        axes.set_ylabel(error)
        axes.set_title(f"density–error front ({len(front)} of {len(points)})", fontsize=9,
                       loc="left")  # fmt: skip
        plain_numbers(axes)
        axes.grid(True, alpha=0.3)
    if path is not None:
        figure.savefig(path)
    return figure


def write_sweep_figures(points: Sequence[SweepPoint], folder: Path) -> list[Path]:
    """The parallel coordinates and one sensitivity figure per swept parameter, in ``folder``."""
    with figure_context():
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise InputError(f"{folder}: cannot create the figures folder ({error})") from None
        written = [folder / PARALLEL_FIGURE]
        parallel_figure(points, written[0])
        if density_pairs(points):
            written.append(folder / DENSITY_FIGURE)
            density_figure(points, written[-1])
        rows = sensitivities(points)
        for parameter in swept_parameters(points):
            path = folder / f"{SENSITIVITY_PREFIX}{parameter}.png"
            sensitivity_figure(parameter, [r for r in rows if r.parameter == parameter], path)
            written.append(path)
    return written


MAX_ROWS = 200
"""Configurations the page lists (best first); ``tune.csv`` has them all."""


def sweep_data(
    store: Any, measures: Sequence[str] | None = None, granularity: str = "sequence"
) -> dict[str, Any]:
    """The page's sweep section: the best configurations with their values, and the figures.

    ``recorded`` false for a database that ``dispeval tune`` did not write. The rows are
    ``tune.csv``'s (the same call ranks them), the figures PNG data URIs (none without
    matplotlib, and ``figures_note`` says why).
    """
    from dispeval_ros.offline.tuning.outputs import stored_sweep

    result = stored_sweep(store, measures, granularity)
    if result is None or not result.rows:
        return {"recorded": False}
    rows = result.rows
    points = [SweepPoint(r.configuration.name, r.configuration.values, r.measures, r.group)
              for r in rows]  # fmt: skip
    swept = swept_parameters(points)
    shown = list(rows[0].measures)
    figures: dict[str, str] = {}
    note = ""
    try:
        with figure_context():
            figures[PARALLEL_FIGURE] = _png(parallel_figure(points, None))
            if density_pairs(points):
                figures[DENSITY_FIGURE] = _png(density_figure(points, None))
            by = sensitivities(points)
            for parameter in swept:
                chosen = [r for r in by if r.parameter == parameter]
                figures[f"{SENSITIVITY_PREFIX}{parameter}.png"] = _png(
                    sensitivity_figure(parameter, chosen, None)
                )
    except ConfigurationError as error:  # matplotlib is the report extra's
        figures, note = {}, str(error)
    return {
        "recorded": True,
        "configurations": len(rows),
        "shown": min(len(rows), MAX_ROWS),
        "parameters": swept,
        "measures": shown,
        "headers": ["configuration", "A* group", "reduced", *swept, *shown],
        "rows": [_row(r, swept) for r in rows[:MAX_ROWS]],
        "objectives": result.objectives,
        "figures": figures,
        "figures_note": note,
    }


def _row(row: Any, swept: Sequence[str]) -> list[Any]:
    """A configuration's name, group, reduced, swept values and measures (None: not finite)."""
    values = [row.configuration.values[p] for p in swept]
    measures = [v if math.isfinite(v) else None for v in row.measures.values()]
    return [row.configuration.name, row.group, row.reduced, *values, *measures]


def _png(figure: Any) -> str:
    """A figure as a ``data:`` URI (the page may show no other image: its CSP)."""
    import base64
    import io

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png")
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")
