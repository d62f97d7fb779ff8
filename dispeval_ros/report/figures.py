"""Static PNG figures of a results database (matplotlib, non-interactive Agg rendering).

The same views as the HTML report, for the report's default selection (or any
:class:`~dispeval_ros.report.data.Selection`): the group table with the interpretation, the
per-frame score curves per method (failures in red), per-criterion bars, the parallel
coordinates of the u2 terms of a group, and where latency is recorded latency against accuracy
and the delay per frame (:mod:`~dispeval_ros.report.latency_figures`). Figures are drawn on
``matplotlib.figure.Figure`` objects (no pyplot, no global backend switch); names are never
parsed as mathtext.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dispeval_ros.core.measures import measure_unit
from dispeval_ros.core.models import ModelResult
from dispeval_ros.errors import InputError
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.report.canvas import (
    figure_context,
    measure_label,
    new_figure,
    plain_numbers,
    require_matplotlib,
)
from dispeval_ros.report.confidence import write_confidence_figures
from dispeval_ros.report.data import (
    Selection,
    _grid,
    common_stamps,
    default_selection,
    evaluate_selection,
)
from dispeval_ros.report.latency import latency_data
from dispeval_ros.report.latency_figures import write_latency_figures
from dispeval_ros.report.recipes import measure_recipe, recipe_values
from dispeval_ros.report.reference import reference_text
from dispeval_ros.report.temporal import temporal_data, write_temporal_figures

FIGURES = ("group_table.png", "curves.png", "criteria_bars.png", "parallel_u2.png")
MAX_CURVES = 24
GROUP_COLOURS = ("#1a9850", "#4575b4", "#f46d43", "#984ea3", "#a6761d", "#e7298a")
FAIL = "#d62728"


def _group_colour(group: int) -> str:
    return GROUP_COLOURS[(group - 1) % len(GROUP_COLOURS)]


def _ordered_methods(models: ModelResult) -> list[str]:
    position = {name: i for i, name in enumerate(models.methods)}
    return sorted(
        models.methods,
        key=lambda m: (models.groups[m], models.middlebury[m], position[m]),
    )


def group_table_figure(
    models: ModelResult, objectives: Sequence[str], path: Path, reference: str | None = None
) -> Any:
    """The group table (sorted by group, then average rank) and the interpretation text.

    ``reference``: what the scores are measured against (:func:`reference_text`), under the title.
    """
    rows = []
    for name in _ordered_methods(models):
        pair = models.reduction.get(name)
        rows.append(
            [
                name,
                str(models.groups[name]),
                f"{pair['u1']:g}" if pair else "",
                f"{pair['u2']:.4f}" if pair else "",
                "yes" if name in models.reduced else "",
                f"{models.middlebury[name]:.2f}",
            ]
        )
    text = "\n".join(
        textwrap.fill(line, 110, subsequent_indent="    ")
        for line in models.interpretation.splitlines()
    )
    lines = text.count("\n") + 1
    figure = new_figure(
        10.0, 0.6 + 0.26 * (len(rows) + 1) + 0.2 * lines + (0.4 if reference else 0)
    )
    table_axes, text_axes = figure.subplots(
        2, 1, gridspec_kw={"height_ratios": [len(rows) + 1, 0.8 * lines]}
    )
    table_axes.axis("off")
    text_axes.axis("off")
    title = f"A* Groups over {len(objectives)} objectives (all minimised)"
    if reference:
        title += "\n" + textwrap.fill(reference, 120)
    table_axes.set_title(title, loc="left", fontsize=11 if not reference else 9.5)
    table = table_axes.table(
        cellText=rows,
        colLabels=["method", "A* group", "u1", "u2", "reduced", "avg rank"],
        bbox=[0.0, 0.0, 1.0, 1.0],
        cellLoc="left",
    )
    table.auto_set_font_size(False)
    table.set_fontsize(9)
    for (row, _), cell in table.get_celld().items():
        if row == 0:
            cell.set_facecolor("#eef1f5")
        elif rows[row - 1][4]:
            cell.set_facecolor("#e6f5ea")
    text_axes.text(0.0, 1.0, text, fontsize=8.5, va="top", ha="left", transform=text_axes.transAxes)
    figure.savefig(path)
    return figure


def _outliers(values: np.ndarray, higher: bool) -> np.ndarray:
    """Outliers of one method's per-frame series: beyond Q3 + 3·IQR (Q1 − 3·IQR if higher)."""
    finite = values[np.isfinite(values)]
    flags = np.zeros(values.shape, dtype=bool)
    if finite.size == 0:
        return flags
    q1, q3 = np.percentile(finite, [25, 75])
    spread = 3 * (q3 - q1)
    if spread <= 0:
        return flags
    with np.errstate(invalid="ignore"):
        return values < q1 - spread if higher else values > q3 + spread


def curves_figure(
    frame_values: np.ndarray,
    missing: np.ndarray,
    methods: Sequence[str],
    measure: str,
    criterion: str,
    higher: bool,
    path: Path,
    separators: Sequence[int] = (),
    unit: str = "",
) -> Any:
    """One small panel per method: its measure per frame; missing frames and outliers in red.

    Frames are numbered from 1 and ticked at whole numbers only; ``unit`` labels the y axis.
    """
    from matplotlib.ticker import MaxNLocator

    shown = list(range(min(len(methods), MAX_CURVES)))
    figure = new_figure(10.0, 0.9 + 0.75 * max(1, len(shown)))
    axes_list = figure.subplots(max(1, len(shown)), 1, sharex=True, squeeze=False)[:, 0]
    frames = np.arange(1, frame_values.shape[0] + 1)
    finite = frame_values[np.isfinite(frame_values)]
    top = float(np.nanmax(finite)) if finite.size else 1.0
    for axes, index in zip(axes_list, shown, strict=False):
        values = frame_values[:, index]
        outliers = _outliers(values, higher)
        regular = np.where(outliers, np.nan, values)
        axes.plot(frames, regular, lw=1.0, color="#1f77b4")
        axes.scatter(frames[outliers], values[outliers], s=12, color=FAIL, zorder=3)
        for frame in frames[missing[:, index] | (~np.isfinite(values) & ~missing[:, index])]:
            axes.axvspan(frame - 0.5, frame + 0.5, color=FAIL, alpha=0.3, lw=0)
        for edge in separators:
            axes.axvline(edge + 0.5, color="#555", lw=0.8)
        axes.set_ylim(0, top * 1.05 if top > 0 else 1.0)
        axes.set_ylabel(methods[index], rotation=0, ha="right", va="center", fontsize=8)
        axes.tick_params(labelsize=7)
        axes.xaxis.set_major_locator(MaxNLocator(integer=True))
        plain_numbers(axes)
    label = measure_label(measure, unit)
    axes_list[0].set_title(
        f"{label} of criterion {criterion} per frame (red: missing/failed frame, undefined "
        "value or outlier)",
        loc="left",
        fontsize=10,
    )
    figure.supylabel(label, fontsize=9)
    if len(methods) > len(shown):
        axes_list[-1].set_xlabel(f"frame (first {len(shown)} of {len(methods)} methods)")
    else:
        axes_list[-1].set_xlabel("frame")
    figure.savefig(path)
    return figure


def criteria_bars_figure(
    values: np.ndarray,
    methods: Sequence[str],
    criteria: Sequence[str],
    groups: Sequence[int],
    measure: str,
    path: Path,
    unit: str = "",
) -> Any:
    """One bar panel per criterion: the measure of each method over the common frames."""
    columns = max(1, min(3, len(criteria)))
    rows = math.ceil(max(1, len(criteria)) / columns)
    figure = new_figure(4.0 * columns, 0.6 + 2.9 * rows)
    axes_grid = figure.subplots(rows, columns, squeeze=False).ravel()
    colours = [_group_colour(g) for g in groups]
    positions = np.arange(len(methods))
    for axes, (c, criterion) in zip(axes_grid, enumerate(criteria), strict=False):
        column = values[:, c]
        axes.bar(positions, np.where(np.isfinite(column), column, 0.0), color=colours)
        axes.set_title(criterion, fontsize=10)
        if len(methods) <= 30:
            axes.set_xticks(positions, list(methods), rotation=60, ha="right", fontsize=7)
        else:
            axes.set_xticks([])
        axes.tick_params(axis="y", labelsize=7)
        axes.set_ylabel(measure_label(measure, unit), fontsize=8)
        plain_numbers(axes)
    for axes in axes_grid[len(criteria) :]:
        axes.axis("off")
    figure.suptitle(
        f"{measure_label(measure, unit)} per criterion over the common frames (colour: A* group)",
        fontsize=10,
    )
    figure.savefig(path)
    return figure


def normalised_terms(matrix: np.ndarray) -> np.ndarray:
    """The u2 terms ``(f − min)/(max − min)`` per objective within the rows (as the models)."""
    values = np.array(matrix, dtype=np.float64)
    values[np.isnan(values)] = np.inf
    terms = np.zeros_like(values)
    if values.shape[0] == 0:
        return terms
    low, high = values.min(axis=0), values.max(axis=0)
    finite = np.isfinite(high) & (high > low)
    terms[:, finite] = (values[:, finite] - low[finite]) / (high[finite] - low[finite])
    infinite = np.isinf(high) & (high > low)
    terms[:, infinite] = np.isinf(values[:, infinite]).astype(np.float64)
    return terms


def parallel_figure(
    matrix: np.ndarray,
    methods: Sequence[str],
    objectives: Sequence[str],
    models: ModelResult,
    group: int,
    path: Path,
) -> Any:
    """Parallel coordinates of the u2 terms of one group; the reduced set drawn thick."""
    rows = [i for i, name in enumerate(methods) if models.groups[name] == group]
    terms = normalised_terms(matrix[rows])
    figure = new_figure(10.0, 4.2 if len(objectives) <= 40 else 3.4)
    axes = figure.add_subplot()
    positions = np.arange(len(objectives))
    reduced = set(models.reduced) if group == 1 else set()
    for p, row in enumerate(rows):
        name = methods[row]
        thick = name in reduced
        axes.plot(
            positions,
            terms[p],
            lw=2.6 if thick else 1.0,
            alpha=1.0 if thick else 0.7,
            label=name + (" (reduced)" if thick else ""),
        )
    if len(objectives) <= 40:
        axes.set_xticks(positions, list(objectives), rotation=60, ha="right", fontsize=7)
        for x in positions:
            axes.axvline(x, color="#ccd", lw=0.6, zorder=0)
    else:
        axes.set_xlabel(f"{len(objectives)} objectives")
    axes.set_ylim(-0.03, 1.03)
    axes.set_ylabel("(f − min)/(max − min) in the group [no unit]")
    axes.set_title(f"u2 terms of A* group {group}", loc="left", fontsize=10)
    if len(rows) <= 15:
        axes.legend(
            fontsize=7,
            loc="upper left",
            bbox_to_anchor=(1.0, 1.0),
            title="method",
            title_fontsize=8,
        )
    figure.savefig(path)
    return figure


def write_figures(
    store: ResultsStore,
    directory: Path,
    selection: Selection | None = None,
    group: int = 1,
    latency: Mapping[str, Any] | None = None,
    temporal: dict[str, Any] | None = None,
) -> list[Path]:
    """Write the PNG figures of ``selection`` (default: the report's) to ``directory``.

    The four of :data:`FIGURES`, and where latency is recorded the two of
    :data:`~dispeval_ros.report.latency_figures.LATENCY_FIGURES` (``latency``: the report
    data's block, made here when not given), and where pairs are recorded
    :data:`~dispeval_ros.report.temporal.TEMPORAL_FIGURE` (``temporal``: likewise).
    """
    require_matplotlib()
    directory = Path(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(f"{directory}: cannot create the figures folder ({error})") from None
    selection = selection or default_selection(store)
    methods, names, matrix, models = evaluate_selection(store, selection)
    if models is None:
        raise InputError(
            f"{store.path}: no objectives to draw (methods or frames every method delivered)"
        )
    all_methods = store.methods()
    criteria = [c for c in store.criteria() if c in selection.criteria]
    sequences = [s for s in store.sequences() if s in selection.sequences]
    measure = next(m for m in store.measures() if m in selection.measures)
    sums, present, stored, info = _grid(store, store.sequences(), all_methods, store.criteria())
    recipe = measure_recipe(measure, info["thresholds"])
    values = recipe_values(recipe, sums, stored.get(measure))
    method_at = [all_methods.index(m) for m in methods]
    criterion_at = [store.criteria().index(c) for c in criteria]
    # frames of the selected sequences, and the common ones for the totals
    offsets, offset = {}, 0
    for sequence in store.sequences():
        offsets[sequence] = offset
        offset += len(store.stamps(sequence))
    frame_rows: list[int] = []
    separators: list[int] = []
    totals = np.zeros((len(methods), len(criteria), sums.shape[-1]))
    for sequence in sequences:
        stamps = store.stamps(sequence)
        if frame_rows:
            separators.append(len(frame_rows))
        frame_rows.extend(offsets[sequence] + i for i in range(len(stamps)))
        common = set(common_stamps(store, sequence, methods, selection.frames))
        for i, stamp in enumerate(stamps):
            if stamp in common:
                block = sums[offsets[sequence] + i][np.ix_(criterion_at, method_at)]
                totals += np.transpose(block, (1, 0, 2))
    first = criterion_at[0] if criterion_at else 0
    frame_values = values[np.ix_(frame_rows, [first], method_at)][:, 0, :]
    missing = ~present[np.ix_(frame_rows, [first], method_at)][:, 0, :].astype(bool)
    bar_values = recipe_values(recipe, totals)
    groups = [models.groups[m] for m in methods]
    relative = any(info["relative"][all_methods.index(m)] for m in methods)
    unit = measure_unit(measure, relative)
    paths = [directory / name for name in FIGURES]
    with figure_context():
        group_table_figure(models, names, paths[0], reference_text(store.config()))
        curves_figure(
            frame_values,
            missing,
            methods,
            measure,
            criteria[0] if criteria else "",
            bool(recipe["higher"]),
            paths[1],
            separators,
            unit,
        )
        criteria_bars_figure(bar_values, methods, criteria, groups, measure, paths[2], unit)
        parallel_figure(matrix, methods, names, models, group, paths[3])
        paths += write_latency_figures(
            store,
            directory,
            latency_data(store) if latency is None else latency,
            criteria[0] if criteria else "",
            measure,
            relative,
        )
        paths += write_temporal_figures(
            directory, temporal_data(store) if temporal is None else temporal
        )
        paths += write_confidence_figures(store, directory)
    return paths
