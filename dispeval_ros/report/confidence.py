"""The sparsification curves of each method's confidence against the oracle's, as a PNG."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dispeval_ros.core.confidence import curve_unit
from dispeval_ros.report.canvas import (
    LINE_COLOURS,
    figure_context,
    measure_label,
    new_figure,
    plain_numbers,
)

if TYPE_CHECKING:
    from dispeval_ros.core.confidence import ConfidenceSums, Curve


SAMPLES = 400
"""Densities each curve is drawn at (besides its group ends)."""


def _drawn(curve: Curve, oracle: bool) -> tuple[np.ndarray, np.ndarray]:
    """The exact curve (:meth:`Curve.at`: curved between group ends) from density 0 to 1."""
    ends = curve.oracle_density if oracle else curve.density
    densities = np.union1d(np.linspace(0.0, 1.0, SAMPLES + 1)[1:], ends)
    values = curve.at(densities, oracle)
    return np.concatenate(([0.0], densities)), np.concatenate((values[:1], values))


def sparsification_figure(
    sums: Mapping[str, ConfidenceSums], path: Path | None, criterion: str = "all"
) -> Any:
    """A panel per measure: each method's curve (solid) and its oracle (dashed), with AUSE."""
    measures = next(iter(sums.values())).measures()
    with figure_context():
        figure = new_figure(3.2 * len(measures), 3.0)
        panels = figure.subplots(1, len(measures), squeeze=False)[0]
        for axes, measure in zip(panels, measures, strict=True):
            for k, (method, one) in enumerate(sums.items()):
                colour = LINE_COLOURS[k % len(LINE_COLOURS)]
                curve = one.curve(criterion, measure)
                axes.plot(*_drawn(curve, oracle=False), color=colour,
                          label=f"{method} (AUSE {curve.ause:.3g})")  # fmt: skip
                axes.plot(*_drawn(curve, oracle=True), color=colour,
                          linestyle="--")  # fmt: skip
            axes.set_xlabel("density")
            axes.set_ylabel(measure_label(measure, curve_unit(measure)))
            axes.set_title(f"{criterion}: {measure} (dashed: oracle)", fontsize=9, loc="left")
            axes.set_xlim(0.0, 1.0)
            plain_numbers(axes)
            axes.grid(True, alpha=0.3)
            axes.legend(fontsize=7)
        if path is not None:
            figure.savefig(path)
    return figure


def write_confidence_figures(store: Any, directory: Path) -> list[Path]:
    """``confidence_<sequence>.png`` per sequence with stored confidence sums (bag --confidence).

    Each method's curves and its oracle's on ``all`` (else the first criterion).
    """
    from dispeval_ros.summary import sequence_confidence

    written: list[Path] = []
    for sequence in store.sequences():
        found = sequence_confidence(store, sequence)
        if not found:
            continue
        pooled = {method: sums for method, (_, _, sums) in found.items()}
        criteria = next(iter(pooled.values())).criteria
        path = directory / f"confidence_{sequence}.png"
        sparsification_figure(pooled, path, "all" if "all" in criteria else criteria[0])
        written.append(path)
    return written
