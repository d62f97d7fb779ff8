"""What every static figure of the report shares: a blank canvas, axis labels, number ticks.

Kept apart from the figure modules (the groups, latency and temporal figures) so that each
of them draws on it without importing another, and none imports the report's data from here.
"""

from __future__ import annotations

from typing import Any

from dispeval_ros.errors import ConfigurationError

LINE_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2")
"""One colour per method in line plots (the page's ``LINE_COLOURS`` in open.js)."""


def require_matplotlib() -> Any:
    """The ``matplotlib`` module, or one line saying how to install it (the ``report`` extra)."""
    try:
        import matplotlib
    except ImportError:
        raise ConfigurationError(
            "PNG figures need matplotlib, which a plain install leaves out: "
            'pip install "dispeval_ros[report]"'
        ) from None
    return matplotlib


def figure_context() -> Any:
    """Draw names as they are (never parsed as mathtext or TeX)."""
    return require_matplotlib().rc_context({"text.parse_math": False, "text.usetex": False})


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
