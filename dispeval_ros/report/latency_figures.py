"""The latency figures of ``dispeval report --png``: latency against accuracy, delay per frame.

One panel per sequence with recorded latency. Latency against accuracy: one point per method
(x: a timing measure, y: an accuracy measure of the sequence's totals over the frames every
method delivered, as the summary compares them), the first A* group over the run's
objectives ringed, the 2-D non-dominated front of the points as a step line. Units come from
:data:`~dispeval_ros.core.timing.TIMING_MEASURES` and the measure registry, through
:func:`~dispeval_ros.report.latency.latency_label` and :func:`measure_label`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from dispeval_ros.core.measures import HIGHER_IS_BETTER, measure_unit
from dispeval_ros.core.timing import TIMING_MEASURES
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.report.canvas import LINE_COLOURS, measure_label, new_figure, plain_numbers
from dispeval_ros.report.latency import DELAY_LABEL, latency_label

LATENCY_FIGURES = ("latency_accuracy.png", "delays.png")
FRONT = "#1a9850"


def front_2d(
    points: Sequence[tuple[float, float]], x_higher: bool = False, y_higher: bool = False
) -> list[int]:
    """Indices of the non-dominated points, in increasing x (NaN points never on it).

    Both coordinates minimised unless ``*_higher``; a point is on the front if no other is at
    least as good in both and better in one. The page's ``front2d`` is the same rule.
    """
    sign_x, sign_y = (-1.0 if x_higher else 1.0), (-1.0 if y_higher else 1.0)
    finite = [
        (sign_x * x, sign_y * y, i)
        for i, (x, y) in enumerate(points)
        if math.isfinite(x) and math.isfinite(y)
    ]
    finite.sort()
    chosen: list[int] = []
    best = math.inf
    for _, y, i in finite:
        if y < best:
            chosen.append(i)
            best = y
    return sorted(chosen, key=lambda i: sign_x * points[i][0])


def accuracy_values(
    store: ResultsStore, sequence: str, methods: Sequence[str], criterion: str, measure: str
) -> list[float]:
    """Each method's ``measure`` on ``criterion`` over the sequence's common frames (NaN: none)."""
    stamps = store.common_stamps(sequence)
    totals = store.sequence_scores(sequence, stamps=stamps) if stamps else {}
    values = []
    for method in methods:
        table = totals.get(method)
        if table is None or criterion not in table.criteria:
            values.append(math.nan)
        else:
            values.append(float(table[criterion][measure]))
    return values


def latency_accuracy_figure(
    panels: Sequence[Mapping[str, Any]], latency: str, measure: str, unit: str, path: Path | None
) -> Any:
    """Latency against accuracy, one panel per sequence; returns the figure (saved to ``path``).

    A panel: ``sequence``, ``criterion``, ``methods``, ``x``, ``y`` (per method) and
    ``first_group`` (the names ringed).
    """
    figure = new_figure(5.2 * len(panels), 4.2)
    axes_list = figure.subplots(1, len(panels), squeeze=False)[0]
    x_higher = TIMING_MEASURES[latency].higher_is_better
    y_higher = measure in HIGHER_IS_BETTER
    for axes, panel in zip(axes_list, panels, strict=True):
        xs, ys, names = panel["x"], panel["y"], panel["methods"]
        front = front_2d(list(zip(xs, ys, strict=True)), x_higher, y_higher)
        if front:
            axes.plot(
                [xs[i] for i in front],
                [ys[i] for i in front],
                drawstyle="steps-post",
                color=FRONT,
                linewidth=1.2,
                label="non-dominated front (these two axes)",
            )
        first = set(panel["first_group"])
        ringed = [i for i, name in enumerate(names) if name in first]
        axes.scatter([xs[i] for i in ringed], [ys[i] for i in ringed], s=140,
                     facecolors="none", edgecolors=FRONT, linewidths=2.0,
                     label="A* group 1 (the run's objectives)")  # fmt: skip
        axes.scatter(xs, ys, s=28, color="#333333", zorder=3)
        for x, y, name in zip(xs, ys, names, strict=True):
            if math.isfinite(x) and math.isfinite(y):
                axes.annotate(name, (x, y), textcoords="offset points", xytext=(6, 4), fontsize=8)
        axes.set_xlabel(latency_label(latency))
        axes.set_ylabel(measure_label(measure, unit))
        plain_numbers(axes)
        axes.set_title(f"{panel['sequence']} · {panel['criterion']}", fontsize=10, loc="left")
        axes.grid(True, alpha=0.3)
        axes.legend(fontsize=7, loc="best")
    if path is not None:
        figure.savefig(path)
    return figure


def delays_figure(panels: Sequence[Mapping[str, Any]], path: Path | None) -> Any:
    """The delay of every frame per method, one panel per sequence (whole frame numbers)."""
    from matplotlib.ticker import MaxNLocator

    figure = new_figure(5.2 * len(panels), 3.6)
    axes_list = figure.subplots(1, len(panels), squeeze=False)[0]
    for axes, panel in zip(axes_list, panels, strict=True):
        for k, (method, rows) in enumerate(panel["delays"].items()):
            axes.plot([frame + 1 for frame, _ in rows], [delay for _, delay in rows],
                      marker=".", linewidth=1, color=LINE_COLOURS[k % len(LINE_COLOURS)],
                      label=method)  # fmt: skip
        axes.xaxis.set_major_locator(MaxNLocator(integer=True))
        axes.set_xlabel("frame")
        axes.set_ylabel(DELAY_LABEL)
        plain_numbers(axes)
        axes.set_title(str(panel["sequence"]), fontsize=10, loc="left")
        axes.grid(True, alpha=0.3)
        axes.legend(fontsize=7, loc="best", title="method", title_fontsize=7)
    if path is not None:
        figure.savefig(path)
    return figure


def latency_panels(
    store: ResultsStore,
    latency: Mapping[str, Any],
    criterion: str,
    measure: str,
    x_measure: str | None = None,
) -> tuple[str, list[dict[str, Any]]]:
    """The x measure and one panel per sequence with recorded latency (the report's block)."""
    x_name = x_measure or str(latency["default"])
    panels = []
    for sequence, block in latency["sequences"].items():
        if not block:
            continue
        methods = list(block["methods"])
        x = [block["values"][m][x_name] for m in methods]
        panels.append(
            {
                "sequence": sequence,
                "criterion": criterion,
                "methods": methods,
                "x": [math.nan if v is None else float(v) for v in x],
                "y": accuracy_values(store, sequence, methods, criterion, measure),
                "first_group": block["first_group"],
                "delays": block["delays"],
            }
        )
    return x_name, panels


def write_latency_figures(
    store: ResultsStore,
    directory: Path,
    latency: Mapping[str, Any] | None,
    criterion: str,
    measure: str,
    relative: bool,
) -> list[Path]:
    """The two latency figures in ``directory``; none where no latency is recorded."""
    if not latency or not latency.get("recorded"):
        return []
    x_name, panels = latency_panels(store, latency, criterion, measure)
    if not panels:
        return []
    paths = [Path(directory) / name for name in LATENCY_FIGURES]
    latency_accuracy_figure(panels, x_name, measure, measure_unit(measure, relative), paths[0])
    delays_figure(panels, paths[1])
    return paths
