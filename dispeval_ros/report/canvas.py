"""What every static figure of the report shares: a blank canvas, axis labels, number ticks.

Kept apart from the figure modules (the groups, latency and temporal figures) so that each
of them draws on it without importing another, and none imports the report's data from here.
"""

from __future__ import annotations

from typing import Any

LINE_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2")
"""One colour per method in line plots (the page's ``LINE_COLOURS`` in open.js)."""


def new_figure(width: float, height: float) -> Any:
    """A ``matplotlib.figure.Figure`` (no pyplot, no global backend switch) of the size in inches."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=100, layout="constrained")


def measure_label(measure: str, unit: str) -> str:
    """An axis label of a measure with its unit (from the registry): ``sze [m]``."""
    return f"{measure} [{unit}]" if unit else measure


def plain_numbers(axes: Any) -> None:
    """Y tick labels as short numbers (``2.5e+06``), never a detached ``1e6`` offset text."""
    from matplotlib.ticker import FuncFormatter

    axes.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:.3g}"))
