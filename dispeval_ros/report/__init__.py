"""The interactive HTML report of a results database (and its static PNG figures).

``data`` reads a results database into a compact JSON-able structure (per-frame accumulator
rows as compressed typed arrays), ``html`` assembles one self-contained HTML file whose
script recomputes the objectives and the models in the browser, ``figures`` draws the same
views as static PNGs, ``maps`` makes the error-map thumbnails from the bags (dense maps, or
a LiDAR run's scattered points), ``latency`` the latency-vs-accuracy view's data and
``reference`` says what the scores are measured against.
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
from dispeval_ros.report.latency import latency_data
from dispeval_ros.report.maps import error_thumbnails
from dispeval_ros.report.reference import reference_text

__all__ = [
    "Selection",
    "build_report_data",
    "decode_arrays",
    "default_selection",
    "error_thumbnails",
    "evaluate_selection",
    "latency_data",
    "reference_text",
    "render_html",
    "selection_objectives",
    "write_report",
]
