"""The sweep's views: each measure's sensitivity to each parameter (hand-worked and against a
plain re-computation) and the figures (a parallel-coordinates line per configuration)."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from dispeval_ros.errors import ConfigurationError
from dispeval_ros.report.sweep import (
    PARALLEL_FIGURE,
    SweepPoint,
    parallel_figure,
    sensitivities,
    swept_parameters,
    write_sweep_figures,
)

pytest.importorskip("matplotlib")


def grid() -> list[SweepPoint]:
    """window ∈ {5, 7, 9} × ratio ∈ {10, 20}, fixed cap; bmp = 2·window + ratio/10."""
    points = []
    for window, ratio in itertools.product((5, 7, 9), (10, 20)):
        values = {"window": window, "ratio": ratio, "cap": 31}
        bmp = 2.0 * window + ratio / 10.0
        group = 1 if (window, ratio) in ((5, 10), (9, 20)) else 2
        points.append(SweepPoint(f"w{window}_u{ratio}", values, {"bmp": bmp, "sze": -bmp}, group))
    return points


def test_a_hand_worked_grid() -> None:
    points = grid()
    assert swept_parameters(points) == ["window", "ratio"]  # cap never changes
    by = {(s.parameter, s.measure): s for s in sensitivities(points)}
    window = by["window", "bmp"]
    assert window.levels == (5.0, 7.0, 9.0)
    # window 5: bmp 11 and 12 → median 11.5, quartiles 11.25 / 11.75; span 19.5 − 11.5 = 8
    assert window.median == (11.5, 15.5, 19.5)
    assert window.low == (11.25, 15.25, 19.25)
    assert window.high == (11.75, 15.75, 19.75)
    assert window.span == 8.0
    ratio = by["ratio", "bmp"]
    assert ratio.median == (15.0, 16.0)  # {11, 15, 19} and {12, 16, 20}
    assert ratio.span == 1.0
    assert by["ratio", "sze"].span == 1.0


def test_against_a_plain_recomputation_with_missing_values() -> None:
    rng = np.random.default_rng(3)
    points = []
    for k in range(60):
        values = {"a": int(rng.integers(0, 4)), "b": int(rng.integers(0, 3))}
        score = float(rng.normal(values["a"], 1.0)) if k % 7 else math.nan
        points.append(SweepPoint(f"c{k}", values, {"m": score}, 1 + k % 3))
    for row in sensitivities(points):
        for level, median, low, high in zip(row.levels, row.median, row.low, row.high, strict=True):
            chosen = sorted(
                p.measures["m"]
                for p in points
                if p.values[row.parameter] == level and math.isfinite(p.measures["m"])
            )
            n = len(chosen)
            middle = (chosen[(n - 1) // 2] + chosen[n // 2]) / 2  # the median by its definition
            assert median == pytest.approx(middle, rel=1e-12)
            assert low <= median <= high
        finite = [m for m in row.median if math.isfinite(m)]
        assert row.span == pytest.approx(max(finite) - min(finite))


def test_figures(tmp_path: Path) -> None:
    points = grid()
    written = write_sweep_figures(points, tmp_path / "figures")
    assert [p.name for p in written] == [
        PARALLEL_FIGURE,
        "sensitivity_window.png",
        "sensitivity_ratio.png",
    ]
    assert all(p.stat().st_size > 1000 for p in written)
    figure = parallel_figure(points, None)
    (axes,) = figure.axes
    drawn = [line for line in axes.lines if len(line.get_xdata()) == 4]  # 2 parameters + 2 measures
    assert len(drawn) == len(points)
    assert [t.get_text() for t in axes.get_xticklabels()] == ["window", "ratio", "bmp", "sze"]


def test_an_empty_sweep_is_one_line() -> None:
    with pytest.raises(ConfigurationError, match="no configuration"):
        sensitivities([])
