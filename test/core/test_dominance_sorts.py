"""Both many-objective sorts (sum-order insertion and bitsets) against the definition.

Large fronts (random, weakly correlated objectives) make the models switch to the bitset sort;
tie-heavy integer objectives (values 0..3: duplicates and weak dominance everywhere) are where
an off-by-one in a tie run or a duplicate entering its twin's dominator set would show. The
reference is a plain numpy O(N²M) dominance table peeled front by front, itself checked
against the pair-by-pair definition of test_models, and moocore where it is installed.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from test_models import _brute_groups, objective_matrices

from dispeval_ros.core import dominance
from dispeval_ros.core.models import _column_order, _dense_ranks, astar_groups, pareto_front
from dispeval_ros.errors import ConfigurationError

Sort = Callable[[np.ndarray, bool], np.ndarray]


def reference_groups(matrix: np.ndarray) -> np.ndarray:
    """A* Groups from the definition: a ≺ b ⇔ a ≤ b everywhere and a ≠ b; peel the unbeaten."""
    values = np.where(np.isnan(matrix), np.inf, matrix)
    n = values.shape[0]
    beaten_by = np.zeros((n, n), dtype=np.bool_)  # [a, b]: a dominates b
    for start in range(0, n, 200):
        block = values[start : start + 200, None, :]
        no_worse = np.all(block <= values[None, :, :], axis=2)
        differs = np.any(block != values[None, :, :], axis=2)
        beaten_by[start : start + 200] = no_worse & differs
    groups = np.zeros(n, dtype=np.int64)
    remaining = np.ones(n, dtype=np.bool_)
    group = 0
    while remaining.any():
        group += 1
        front = remaining & ~beaten_by[remaining].any(axis=0)
        groups[front] = group
        remaining &= ~front
    return groups


def moocore_groups(matrix: np.ndarray) -> np.ndarray | None:
    """moocore's fronts (1-based) when the test extra is installed."""
    try:
        import moocore
    except ImportError:
        return None
    return np.asarray(moocore.pareto_rank(matrix)) + 1


def ranks_of(matrix: np.ndarray) -> np.ndarray:
    values = np.where(np.isnan(matrix), np.inf, matrix)
    return np.ascontiguousarray(_dense_ranks(*_column_order(values)))


def by_insertion(ranks: np.ndarray, first_only: bool) -> np.ndarray:
    result = dominance.fronts_by_sum(ranks, first_only)
    assert result is not None
    return result


def by_bitsets(ranks: np.ndarray, first_only: bool) -> np.ndarray:
    result = dominance.fronts_bitset(ranks, first_only)
    assert result is not None
    return result


SORTS: dict[str, Sort] = {"insertion": by_insertion, "bitset": by_bitsets}


@pytest.fixture(params=["insertion", "bitset", "chosen"])
def sort(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """Route every model through one sort (``chosen``: the models' own choice), tiny N too."""
    monkeypatch.setattr(dominance, "SMALL_PROBLEM", 0)
    if request.param in SORTS:
        monkeypatch.setattr(dominance, "fronts_many", SORTS[request.param])
    return str(request.param)


def random_matrix(seed: int, n: int, m: int) -> np.ndarray:
    return np.random.default_rng(seed).random((n, m))


def tied_matrix(seed: int, n: int, m: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 4, size=(n, m)).astype(np.float64)


def weak_matrix(seed: int, n: int, m: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.random((n, 1)) + rng.normal(0.0, 0.6, size=(n, m))


def test_reference_is_the_definition() -> None:
    for seed in range(5):
        for matrix in (tied_matrix(seed, 40, 3), random_matrix(seed, 40, 4)):
            matrix[np.random.default_rng(seed).random(matrix.shape) < 0.05] = np.nan
            assert reference_groups(matrix).tolist() == _brute_groups(matrix)


@pytest.mark.parametrize("objectives", [3, 4, 8, 12])
@pytest.mark.parametrize("make", [random_matrix, tied_matrix, weak_matrix])
def test_groups_and_front_match_reference_and_moocore(
    sort: str, make: Callable[[int, int, int], np.ndarray], objectives: int
) -> None:
    matrix = make(objectives, 1200, objectives)
    expected = reference_groups(matrix)
    assert astar_groups(matrix).tolist() == expected.tolist()
    assert pareto_front(matrix).tolist() == (expected == 1).tolist()
    theirs = moocore_groups(matrix)
    if theirs is not None:
        assert theirs.tolist() == expected.tolist()


def test_tie_runs_duplicates_and_nan(sort: str) -> None:
    """Integer objectives 0..3 with NaN (= +inf): ties in every objective, many twin rows."""
    for seed in range(4):
        matrix = tied_matrix(seed, 500, 5)
        matrix[np.random.default_rng(seed).random(matrix.shape) < 0.05] = np.nan
        matrix[::7] = matrix[3]  # one row repeated many times
        assert astar_groups(matrix).tolist() == reference_groups(matrix).tolist()


@settings(max_examples=200, deadline=None)
@given(matrix=objective_matrices())
def test_small_matrices_match_the_definition(matrix: np.ndarray) -> None:
    """Every sort on the hypothesis matrices of test_models (signed zeros, NaN, +inf, twins)."""
    expected = _brute_groups(matrix)
    if matrix.shape[1] < 3:
        return  # one or two objectives never reach these sorts
    ranks = ranks_of(matrix)
    for name, run in SORTS.items():
        assert run(ranks, False).tolist() == expected, name
        assert run(ranks, True).tolist() == [min(g, 2) for g in expected], name


def test_edge_cases(sort: str) -> None:
    assert astar_groups(np.zeros((0, 4))).tolist() == []
    assert astar_groups([[1.0, 2.0, 3.0]]).tolist() == [1]
    assert pareto_front([[1.0, 2.0, 3.0]]).tolist() == [True]
    assert astar_groups([[3.0], [1.0], [1.0], [2.0]]).tolist() == [3, 1, 1, 2]
    assert astar_groups([[1.0, 1.0, 1.0]] * 3).tolist() == [1, 1, 1]
    assert astar_groups([[math.nan, 1.0, 1.0], [1.0, 1.0, 1.0]]).tolist() == [2, 1]
    with pytest.raises(ConfigurationError, match="-inf"):
        astar_groups([[-math.inf, 1.0, 1.0], [0.0, 0.0, 0.0]])


def test_bitsets_over_several_chunks_and_many_fronts(monkeypatch: pytest.MonkeyPatch) -> None:
    """Candidate sets in chunks of 64 rows, and more fronts than the 16 first foreseen."""
    monkeypatch.setattr(dominance, "_CHUNK_WORDS", 1)
    rng = np.random.default_rng(5)
    quality = rng.gamma(2.0, 2.0, size=(700, 1))
    correlated = np.round(quality + rng.normal(0.0, 0.8, size=(700, 4)))
    for matrix in (correlated, tied_matrix(6, 700, 6), random_matrix(7, 700, 12)):
        expected = reference_groups(matrix)
        ranks = ranks_of(matrix)
        assert by_bitsets(ranks, False).tolist() == expected.tolist()
        assert by_bitsets(ranks, True).tolist() == np.minimum(expected, 2).tolist()
    assert reference_groups(correlated).max() > 16


def test_too_many_fronts_for_bitsets_falls_back(monkeypatch: pytest.MonkeyPatch) -> None:
    chain = np.arange(300, dtype=float)[::-1, None] * np.ones((1, 3))
    ranks = ranks_of(chain)
    monkeypatch.setattr(dominance, "_FRONT_WORDS", 10 * ranks.shape[0] // 64)
    assert dominance.fronts_bitset(ranks, False) is None  # 300 fronts, room for 10
    monkeypatch.setattr(dominance, "WORDS_PER_COMPARISON", math.inf)  # insertion gives up
    assert dominance.fronts_many(ranks, False).tolist() == list(range(300, 0, -1))
    assert astar_groups(chain).tolist() == list(range(300, 0, -1))


def test_choice_follows_the_budget(monkeypatch: pytest.MonkeyPatch) -> None:
    """Huge fronts go to the bitsets, correlated sweeps stay with the insertion; same fronts."""
    calls: list[str] = []
    original = dominance.fronts_bitset

    def spy(ranks: np.ndarray, first_only: bool) -> np.ndarray | None:
        calls.append("bitset")
        return original(ranks, first_only)

    monkeypatch.setattr(dominance, "fronts_bitset", spy)
    wide = random_matrix(8, 3000, 12)
    assert dominance.fronts_by_sum(ranks_of(wide), False, budget=0.0) is None
    assert astar_groups(wide).tolist() == reference_groups(wide).tolist()
    assert calls == ["bitset"]
    calls.clear()
    rng = np.random.default_rng(9)
    sweep = np.round(rng.gamma(2.0, 5.0, size=(3000, 1)) + rng.normal(0.0, 0.7, size=(3000, 12)))
    assert astar_groups(sweep).tolist() == reference_groups(sweep).tolist()
    assert calls == []
