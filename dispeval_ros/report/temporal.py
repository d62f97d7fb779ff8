"""The temporal-consistency part of the report: pooled TEPE, the ego-motion residual, per pair.

Per sequence and method the pair measures of ``--temporal`` (TEPE against the GT's own change)
and the ego-motion residual of ``--egomotion`` (the estimate moved by the camera's motion and
compared with the next one: temporal noise measured without ground truth, not accuracy; its
criteria keep their ``gtfree:`` label), the LiDAR drift between scans (``drift:``) and the
flicker of a static camera where recorded, and per pair of consecutive frames each method's
TEPE and mean |residual| for the per-frame plot.

The pooled values are summary.json's ``temporal`` and ``egomotion`` entries
(:meth:`~dispeval_ros.summary.SequenceSummary.temporal_dict`, ``egomotion_dict``): the same
functions make both. A database without the pairs tables, or with no pair in them, gives
``recorded`` false, and the page shows nothing of it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

from dispeval_ros.core.lidar_drift import LABEL as DRIFT_LABEL
from dispeval_ros.core.objectives import EGOMOTION_OBJECTIVES
from dispeval_ros.core.temporal import pair_unit
from dispeval_ros.io.jsonio import json_safe
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.report.canvas import LINE_COLOURS, new_figure, plain_numbers
from dispeval_ros.summary import FLICKER_LABEL, SequenceSummary, summarize

T = TypeVar("T")

NOISE_NOTE = (
    "ego-motion residual: the estimate at a frame moved by the camera's motion (/tf) into the "
    "next frame and compared with the estimate there, on gtfree: criteria; temporal noise "
    "measured without ground truth, not accuracy (a constant offset is fitted and removed)"
)
"""How the page and the figure label the residual: one wording."""
TEPE_NOTE = (
    "TEPE: |(d̂ₜ − d̂ₜ₊₁) − (dₜ − dₜ₊₁)| at the same pixel over the pixels with GT in both "
    "frames, pooled over the sequence's pairs by their sums"
)
SERIES_TEPE = "tepe"
"""The pair measure the per-frame plot draws."""
SERIES_RESIDUAL = "mean_abs"
"""The residual value the per-frame plot draws (:data:`EGOMOTION_OBJECTIVES`' key)."""
TEPE_LABEL = "tepe [px]"
RESIDUAL_LABEL = "ego-motion residual, mean |r| [px] (noise)"


def residual_columns(thresholds: tuple[float, ...]) -> list[str]:
    """The residual's values the table shows: those that can be objectives, ``bad_X`` expanded."""
    columns: list[str] = []
    for key, _ in EGOMOTION_OBJECTIVES.values():
        columns += [f"bad_{t:g}" for t in thresholds] if key == "bad_X" else [key]
    return columns


def _criterion(criteria: tuple[str, ...]) -> str:
    return "all" if "all" in criteria else criteria[0]


def _ordered(store: ResultsStore, found: dict[str, T] | None) -> list[tuple[str, T]]:
    """``found``'s items in the methods' order (then first seen), as the pooled tables are."""
    found = found or {}
    methods = store.methods()
    return [
        (m, found[m]) for m in [*methods, *(m for m in found if m not in methods)] if m in found
    ]


def _series(store: ResultsStore, summary: SequenceSummary) -> tuple[dict[str, Any], dict[str, Any]]:
    """Per method, ``[frame, value]`` per pair (frame: the later one's index in the sequence)."""
    frame_of = {stamp: i for i, stamp in enumerate(store.stamps(summary.sequence))}
    tepe: dict[str, Any] = {}
    for method, pairs in _ordered(store, store.pair_series(summary.sequence)):
        criterion = _criterion(pairs[0][1].criteria)
        tepe[method] = {
            "criterion": criterion,
            "values": [
                [frame_of[stamp], p[criterion][SERIES_TEPE]]
                for stamp, p in pairs
                if stamp in frame_of and SERIES_TEPE in p.measures
            ],
        }
    residual: dict[str, Any] = {}
    for method, moved in _ordered(store, store.motion_series(summary.sequence)):
        criterion = _criterion(moved[0][1].criteria)
        residual[method] = {
            "criterion": "gtfree:" + criterion,
            "values": [
                [frame_of[stamp], s.summary(criterion)[SERIES_RESIDUAL]]
                for stamp, s in moved
                if stamp in frame_of
            ],
        }
    return tepe, residual


def drift_columns(entry: dict[str, Any] | None) -> list[str]:
    """The LiDAR drift's values the table shows (their units are the entry's)."""
    if not entry:
        return []
    thresholds = entry["options"]["thresholds"]
    return ["counted", "mean", "rms", *(f"bad_{t:g}" for t in thresholds), "bias_drift"]


def flicker_columns(entry: dict[str, Any] | None) -> list[str]:
    """Flicker's values the table shows: the mean spread, its rms, the share above each level."""
    if not entry or not entry["methods"]:
        return []
    first = next(iter(entry["methods"].values()))["criteria"]
    values = next(iter(first.values())) if first else {}
    return ["mean_abs", "rms", *(k for k in values if k.startswith("bad_"))]


def _sequence(store: ResultsStore, summary: SequenceSummary) -> dict[str, Any] | None:
    temporal, egomotion = summary.temporal_dict() or {}, summary.egomotion_dict() or {}
    drift, flicker = summary.drift_dict(), summary.flicker_dict()
    flicker = flicker if flicker and flicker["methods"] else None  # (a table with no window)
    if not temporal and not egomotion and not flicker:
        return None
    tepe_series, residual_series = _series(store, summary)
    motion = summary.motion or {}
    thresholds = next(iter(motion.values()))[1].thresholds if motion else ()
    first_pairs = next(iter((summary.pairs or {}).values()), None)
    return {
        "temporal": temporal or None,
        "tepe_measures": list(first_pairs.measures) if first_pairs else [],
        "tepe_headers": [
            f"{m} [{pair_unit(m)}]" if pair_unit(m) else m
            for m in (first_pairs.measures if first_pairs else ())
        ],
        "egomotion": egomotion or None,
        "residual_columns": residual_columns(tuple(thresholds)),
        "tepe_series": tepe_series,
        "residual_series": residual_series,
        "frames": len(store.stamps(summary.sequence)),
        "drift": drift,
        "drift_columns": drift_columns(drift),
        "flicker": flicker,
        "flicker_columns": flicker_columns(flicker),
    }


def temporal_data(store: ResultsStore) -> dict[str, Any]:
    """The report's temporal block (``recorded`` false without pairs: see the module)."""
    if not (store.records_pairs() or store.records_motion() or store.records_flicker()):
        return {"recorded": False}
    summary = summarize(store)  # the pooled pairs do not depend on the objectives
    sequences = {s.sequence: _sequence(store, s) for s in summary.sequences}
    found = {name: block for name, block in sequences.items() if block}
    if not found:
        return {"recorded": False}
    return json_safe(
        {
            "recorded": True,
            "preset": summary.temporal,
            "tepe_note": TEPE_NOTE,
            "noise_note": NOISE_NOTE,
            "tepe_label": TEPE_LABEL,
            "residual_label": RESIDUAL_LABEL,
            "drift_note": DRIFT_LABEL,
            "flicker_note": FLICKER_LABEL,
            "sequences": found,
        }
    )


TEMPORAL_FIGURE = "temporal.png"
"""The per-frame figure of ``dispeval report --png`` (where pairs are recorded)."""


def temporal_figure(temporal: dict[str, Any], path: Path | None) -> Any:
    """Per sequence, each method's TEPE and ego-motion residual per pair of frames.

    One row per sequence, a column for TEPE and one for the residual where recorded; the
    residual's panel is titled as noise (:data:`NOISE_NOTE`'s first words), never accuracy.
    """
    from matplotlib.ticker import MaxNLocator

    panels = [
        (name, kind, block[f"{kind}_series"])
        for name, block in temporal["sequences"].items()
        for kind in ("tepe", "residual")
        if block[f"{kind}_series"]
    ]
    figure = new_figure(5.2 * min(2, len(panels)), 3.4 * ((len(panels) + 1) // 2))
    axes_list = figure.subplots((len(panels) + 1) // 2, min(2, len(panels)), squeeze=False)
    for axes, (name, kind, series) in zip(axes_list.ravel(), panels, strict=False):
        for k, (method, entry) in enumerate(series.items()):
            rows = entry["values"]
            values = [float("nan") if v is None else v for _, v in rows]
            axes.plot([frame + 1 for frame, _ in rows], values, marker=".", linewidth=1,
                      color=LINE_COLOURS[k % len(LINE_COLOURS)], label=method)  # fmt: skip
            criterion = entry["criterion"]
        axes.xaxis.set_major_locator(MaxNLocator(integer=True))
        axes.set_xlabel("frame (the later of each pair)")
        axes.set_ylabel(temporal["tepe_label"] if kind == "tepe" else temporal["residual_label"])
        plain_numbers(axes)
        what = "TEPE" if kind == "tepe" else "ego-motion residual: temporal noise, no GT"
        axes.set_title(f"{name} · {criterion} · {what}", fontsize=9, loc="left")
        axes.grid(True, alpha=0.3)
        axes.legend(fontsize=7, loc="best", title="method", title_fontsize=7)
    for axes in axes_list.ravel()[len(panels) :]:
        axes.set_visible(False)
    if path is not None:
        figure.savefig(path)
    return figure


def write_temporal_figures(directory: Path, temporal: dict[str, Any] | None) -> list[Path]:
    """:data:`TEMPORAL_FIGURE` in ``directory``; none where no pair is recorded."""
    if not temporal or not temporal.get("recorded"):
        return []
    series = [
        b[k] for b in temporal["sequences"].values() for k in ("tepe_series", "residual_series")
    ]
    if not any(series):  # flicker or drift only: their tables, no per-pair plot
        return []
    path = Path(directory) / TEMPORAL_FIGURE
    temporal_figure(temporal, path)
    return [path]
