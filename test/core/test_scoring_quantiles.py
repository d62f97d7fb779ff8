"""Error quantiles aNN: floor index, order statistics of sorted parts, under ``ignore``.

Conventions of the code under test: reference.py (METHOD.md §1–3).
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scoring_support import NAN

from dispeval_ros.core.evaluator import Evaluator, kth_smallest


def test_quantiles_at_floor_index_without_interpolation() -> None:
    # 10 errors 0..9 (GT 100, E = 100 + i): a50 = sorted[5] = 5, a90 = sorted[9] = 9;
    # a75 = sorted[⌊7.5⌋] = 7 (an interpolating quantile would give 6.75)
    gt = np.full((2, 5), 100.0, np.float32)
    est = (100.0 + np.arange(10, dtype=np.float32)[::-1]).reshape(2, 5)
    got = Evaluator(criteria=("all",), measures=("a50", "a90", "a75", "a10")).score(gt, est)
    assert got["all"]["a50"] == 5.0
    assert got["all"]["a90"] == 9.0
    assert got["all"]["a75"] == 7.0
    assert got["all"]["a10"] == 1.0


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.lists(st.integers(0, 40).map(lambda v: v / 4), max_size=300).map(sorted),
        min_size=1,
        max_size=9,
    ),
    st.data(),
)
def test_kth_smallest_of_sorted_parts_is_the_sorted_union(
    parts: list[list[float]], data: st.DataObject
) -> None:
    union = np.sort(np.concatenate([np.asarray(p, dtype=np.float64) for p in parts]))
    if not union.size:
        return
    ks = data.draw(st.lists(st.integers(0, union.size - 1), min_size=1, max_size=5))
    found = kth_smallest([np.asarray(p, dtype=np.float64) for p in parts], ks)
    assert found == {k: float(union[k]) for k in ks}


def test_kth_smallest_on_many_values_with_few_probes() -> None:
    rng = np.random.default_rng(4)
    parts = [np.sort(rng.gamma(2.0, 3.0, n).round(2)) for n in (90_000, 0, 7, 300_000, 1)]
    union = np.sort(np.concatenate(parts))
    ks = [0, 1, union.size // 2, union.size * 9 // 10, union.size - 1]
    assert kth_smallest(parts, ks) == {k: float(union[k]) for k in ks}


def test_quantiles_under_ignore_use_evaluated_points_only() -> None:
    # 7 valid errors 0..6 and 3 holes: ignore → N = 7, a50 = [3] = 3, a90 = [6] = 6;
    # thesis → holes have e = 100: N = 10, a50 = [5] = 5, a90 = [9] = 100
    gt = np.full((1, 10), 100.0, np.float32)
    est = np.array([[100, 101, 102, 103, 104, 105, 106, NAN, 0, -1]], np.float32)
    ignore = Evaluator(criteria=("all",), missing="ignore").score(gt, est)["all"]
    thesis = Evaluator(criteria=("all",), missing="thesis").score(gt, est)["all"]
    assert (ignore["a50"], ignore["a90"]) == (3.0, 6.0)
    assert (thesis["a50"], thesis["a90"]) == (5.0, 100.0)
