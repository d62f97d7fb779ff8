"""The interactive HTML report of a results database (and its static PNG figures).

``data`` reads a results database into a compact JSON-able structure (per-frame accumulator
rows as compressed typed arrays), ``html`` assembles one self-contained HTML file whose
script recomputes the objectives and the models in the browser, ``figures`` draws the same
views as static PNGs.
"""

from dispeval_ros.report.data import (
    Selection,
    build_report_data,
    decode_arrays,
    default_selection,
    evaluate_selection,
    selection_objectives,
)
from dispeval_ros.report.html import render_html, write_report

__all__ = [
    "Selection",
    "build_report_data",
    "decode_arrays",
    "default_selection",
    "evaluate_selection",
    "render_html",
    "selection_objectives",
    "write_report",
]
