"""Tests of the evaluation models (METHOD.md §5), pinned to hand-worked cases and properties."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from dispeval_ros.core import dominance
from dispeval_ros.core.models import (
    ModelResult,
    Reduction,
    astar_groups,
    dominates,
    evaluate_models,
    front_reduction,
    interpretation,
    measure_consistency,
    middlebury_ranks,
    pareto_front,
)
from dispeval_ros.errors import ConfigurationError, DispevalError

# METHOD.md §6: a=(1,4) b=(2,2) c=(3,3) d=(4,1).
WORKED_METHODS = ["a", "b", "c", "d"]
WORKED = np.array([[1.0, 4.0], [2.0, 2.0], [3.0, 3.0], [4.0, 1.0]])


# --- dominance ---------------------------------------------------------------------------


def test_dominance_definition() -> None:
    assert dominates([2, 2], [3, 3])  # b ≺ c
    assert dominates([1, 3], [1, 4])  # equal on one objective, better on the other
    assert not dominates([3, 3], [2, 2])
    assert not dominates([1, 4], [3, 3])  # incomparable
    assert not dominates([3, 3], [1, 4])
    assert dominates([0], [1])


def test_equal_vectors_do_not_dominate_each_other() -> None:
    assert not dominates([1, 2], [1, 2])
    assert not dominates([5], [5])


def test_dominance_rejects_different_lengths() -> None:
    with pytest.raises(ConfigurationError, match="same length"):
        dominates([1, 2], [1, 2, 3])


def test_nan_is_worst_possible() -> None:
    assert dominates([1.0], [math.nan])
    assert not dominates([math.nan], [1.0])
    assert not dominates([math.nan, 1.0], [math.nan, 1.0])  # NaN ties NaN
    assert dominates([math.nan, 1.0], [math.nan, 2.0])
    assert pareto_front([[math.nan, 1.0], [1.0, 2.0]]).tolist() == [True, True]
    assert astar_groups([[math.nan, 1.0], [1.0, 1.0]]).tolist() == [2, 1]


def test_negative_infinity_is_rejected() -> None:
    with pytest.raises(ConfigurationError, match="-inf"):
        pareto_front([[-math.inf, 1.0], [0.0, 0.0]])


# --- A* and A* Groups --------------------------------------------------------------------


def test_worked_check_front_and_groups() -> None:
    assert pareto_front(WORKED).tolist() == [True, True, False, True]
    assert astar_groups(WORKED).tolist() == [1, 1, 2, 1]


def test_equal_vectors_share_the_front() -> None:
    matrix = [[1, 2], [1, 2], [2, 3]]
    assert pareto_front(matrix).tolist() == [True, True, False]
    assert astar_groups(matrix).tolist() == [1, 1, 2]


def test_single_method() -> None:
    assert pareto_front([[3.0, 1.0]]).tolist() == [True]
    assert astar_groups([[3.0, 1.0]]).tolist() == [1]
    assert middlebury_ranks([[3.0, 1.0]]).tolist() == [1.0]
    reduction = front_reduction([[3.0, 1.0]])
    assert reduction.u1.tolist() == [2.0]
    assert reduction.u2.tolist() == [0.0]
    assert reduction.reduced.tolist() == [True]


def test_single_objective_groups_are_ranks_with_ties() -> None:
    values = [[3.0], [1.0], [3.0], [2.0], [1.0]]
    # Groups are contiguous (dense ranks); Middlebury ranks are competition ranks.
    assert astar_groups(values).tolist() == [3, 1, 3, 2, 1]
    assert pareto_front(values).tolist() == [False, True, False, False, True]
    assert middlebury_ranks(values).tolist() == [4.0, 1.0, 4.0, 3.0, 1.0]


def test_chain_gives_one_group_per_method() -> None:
    matrix = np.arange(6, dtype=float)[::-1, None] * np.ones((1, 3))
    assert astar_groups(matrix).tolist() == [6, 5, 4, 3, 2, 1]


def test_group_three_levels() -> None:
    # x dominates y and z; y, z incomparable; w is dominated by z only.
    matrix = [[0, 0], [1, 3], [3, 1], [4, 2]]
    assert astar_groups(matrix).tolist() == [1, 2, 2, 3]


def test_empty_matrix() -> None:
    empty = np.zeros((0, 3))
    assert pareto_front(empty).tolist() == []
    assert astar_groups(empty).tolist() == []
    assert middlebury_ranks(empty).tolist() == []


def test_large_inputs_agree_with_brute_force() -> None:
    """Large inputs (timings belong to bench/, never to unit tests)."""
    rng = np.random.default_rng(7)
    wide = rng.random((100, 1000))
    front = pareto_front(wide)
    brute = [not any(dominates(other, row) for other in wide) for row in wide]
    assert front.tolist() == brute
    tall = rng.random((1000, 50))
    groups = astar_groups(tall)
    assert np.array_equal(groups == 1, pareto_front(tall))


# --- front reduction ---------------------------------------------------------------------


def test_worked_check_front_reduction() -> None:
    group = WORKED[[0, 1, 3]]  # a, b, d
    reduction = front_reduction(group)
    assert isinstance(reduction, Reduction)
    assert reduction.u1.tolist() == [4.0, 4.0, 4.0]
    assert reduction.u2 == pytest.approx([1.0, 2.0 / 3.0, 1.0])
    assert reduction.reduced.tolist() == [False, True, False]


def test_competition_ranking_ties() -> None:
    reduction = front_reduction([[2.0], [2.0], [9.0]])
    assert reduction.u1.tolist() == [1.0, 1.0, 3.0]  # 1, 1, 3 — not 1, 1, 2
    assert reduction.u2.tolist() == [0.0, 0.0, 1.0]
    assert reduction.reduced.tolist() == [True, True, False]


def test_constant_objective_contributes_nothing_to_u2() -> None:
    reduction = front_reduction([[5.0, 0.0], [5.0, 2.0], [5.0, 1.0]])
    assert reduction.u1.tolist() == [2.0, 4.0, 3.0]  # 1 + rank in the second objective
    assert reduction.u2.tolist() == [0.0, 1.0, 0.5]
    assert reduction.reduced.tolist() == [True, False, False]


def test_infinite_value_in_u2_is_the_limit() -> None:
    # x = (NaN→inf, 0), y = (1, 1), z = (2, 0.5); ranks: x (3, 1), y (1, 3), z (2, 2).
    reduction = front_reduction([[math.nan, 0.0], [1.0, 1.0], [2.0, 0.5]])
    assert reduction.u1.tolist() == [4.0, 4.0, 4.0]
    assert reduction.u2.tolist() == [1.0, 1.0, 0.5]
    assert reduction.reduced.tolist() == [False, False, True]
    all_missing = front_reduction([[math.nan, 0.0], [math.nan, 1.0]])
    assert all_missing.u2.tolist() == [0.0, 1.0]


def test_u2_rounding_does_not_create_dominance() -> None:
    # x and y have the same u1 (7) and mathematically the same u2 (0.6), but summing the
    # fractions in a different order differs in the last bit; p and q fix min 0 and max 1.
    matrix = [[0.1, 0.2, 0.3], [0.3, 0.2, 0.1], [0.0, 1.0, 0.0], [1.0, 0.0, 1.0]]
    reduction = front_reduction(matrix)
    assert reduction.u1.tolist() == [7.0, 7.0, 6.0, 9.0]
    assert reduction.u2[0] == pytest.approx(reduction.u2[1])
    assert reduction.reduced.tolist() == [True, True, True, False]


# --- Middlebury --------------------------------------------------------------------------


def test_worked_check_middlebury() -> None:
    # Objective 1 ranks a..d: 1, 2, 3, 4; objective 2: 4, 2, 3, 1.
    assert middlebury_ranks(WORKED).tolist() == [2.5, 2.0, 3.0, 2.5]


def test_middlebury_with_ties() -> None:
    # Objective 1: 1, 1, 3 (competition); objective 2: 1, 2, 2.
    assert middlebury_ranks([[1, 1], [1, 2], [2, 2]]).tolist() == [1.0, 1.5, 2.5]


# --- measure consistency -----------------------------------------------------------------


def test_measure_consistency_hand_worked() -> None:
    # Pairs (0,1): same vs better ✗; (0,2): better vs better ✓; (1,2): better vs same ✗.
    assert measure_consistency([1, 1, 2], [1, 2, 2]) == pytest.approx(1 / 3)
    # (0,1) ✗ (0,2) ✓ (0,3) ✓ (1,2) ✓ (1,3) ✗ (2,3) ✓ → 4/6.
    assert measure_consistency([1, 2, 3, 1], [2, 1, 3, 2]) == pytest.approx(2 / 3)
    # Only the order matters, not the group numbers.
    assert measure_consistency([1, 3], [1, 2]) == 1.0
    assert measure_consistency([1, 2], [2, 1]) == 0.0


def test_measure_consistency_small_and_mappings() -> None:
    assert measure_consistency([], []) == 1.0
    assert measure_consistency([1], [4]) == 1.0
    by_name = measure_consistency({"x": 1, "y": 1, "z": 2}, {"z": 2, "y": 2, "x": 1})
    assert by_name == pytest.approx(1 / 3)


def _consistency_by_pairs(first: list[int], second: list[int]) -> float:
    """Every pair compared: the definition, for small inputs."""
    n = len(first)
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    agree = sum(np.sign(first[i] - first[j]) == np.sign(second[i] - second[j]) for i, j in pairs)
    return agree / len(pairs) if pairs else 1.0


@settings(max_examples=200, deadline=None)
@given(
    st.integers(2, 40).flatmap(
        lambda n: st.tuples(
            st.lists(st.integers(1, 5), min_size=n, max_size=n),
            st.lists(st.integers(1, 5), min_size=n, max_size=n),
        )
    )
)
def test_measure_consistency_equals_every_pair_compared(
    groups: tuple[list[int], list[int]],
) -> None:
    first, second = groups
    assert measure_consistency(first, second) == pytest.approx(
        _consistency_by_pairs(first, second), abs=1e-12
    )


def test_measure_consistency_of_a_sweep_without_pair_arrays() -> None:
    """10⁴ methods (5·10⁷ pairs): counted, not listed; known answers on structured cases."""
    n = 10_000
    ranks = np.arange(n)
    assert measure_consistency(ranks, ranks) == 1.0
    assert measure_consistency(ranks, ranks[::-1]) == 0.0
    halves = ranks // (n // 2)  # two groups in both: only cross-half pairs agree
    assert measure_consistency(halves, halves) == 1.0
    assert measure_consistency(halves, ranks) == pytest.approx((n // 2) ** 2 / (n * (n - 1) / 2))


def test_measure_consistency_rejects_mismatches() -> None:
    with pytest.raises(ConfigurationError, match="same methods"):
        measure_consistency([1, 2], [1, 2, 3])
    with pytest.raises(ConfigurationError, match="same methods"):
        measure_consistency({"x": 1}, {"y": 1})
    with pytest.raises(ConfigurationError, match="both"):
        measure_consistency({"x": 1}, [1])


# --- interpretation ----------------------------------------------------------------------


def test_interpretation_single_superior_method() -> None:
    text = interpretation(["x", "y", "z"], [1, 2, 2], ["x"])
    assert text.splitlines() == [
        "A* = {x}: a single method of superior performance (it dominates every other method).",
        "Group 2: 2 methods of comparable performance: y, z "
        "(mutually incomparable; each dominated by at least one method of group 1).",
        "Front reduction of A* (chosen without weights, by the (u1, u2) front): x.",
    ]


def test_interpretation_worked_check() -> None:
    text = interpretation(WORKED_METHODS, [1, 1, 2, 1], ["b"])
    assert text.splitlines() == [
        "A* = {a, b, d}: a set of methods of comparable performance "
        "(mutually incomparable; every method outside A* is dominated by at least one of them).",
        "Group 2: a single method: c (dominated by at least one method of group 1).",
        "Front reduction of A* (chosen without weights, by the (u1, u2) front): b.",
    ]


def test_interpretation_several_reduced_and_mapping() -> None:
    text = interpretation(["p", "q"], {"q": 1, "p": 1}, ["q", "p"])
    assert text.splitlines()[-1] == (
        "Front reduction of A* (chosen without weights, by the (u1, u2) front): p, q "
        "(incomparable in (u1, u2))."
    )


def test_interpretation_rejects_inconsistent_input() -> None:
    with pytest.raises(ConfigurationError, match="one group per method"):
        interpretation(["x", "y"], [1], ["x"])
    with pytest.raises(ConfigurationError, match="evaluated methods"):
        interpretation(["x"], [1], ["w"])


# --- evaluate_models ---------------------------------------------------------------------


def test_evaluate_models_worked_check() -> None:
    result = evaluate_models(WORKED_METHODS, WORKED)
    assert isinstance(result, ModelResult)
    assert result.methods == WORKED_METHODS
    assert result.groups == {"a": 1, "b": 1, "c": 2, "d": 1}
    assert result.astar == ["a", "b", "d"]
    assert set(result.reduction) == {"a", "b", "d"}
    assert result.reduction["a"] == {"u1": 4.0, "u2": 1.0}
    assert result.reduction["b"]["u1"] == 4.0
    assert result.reduction["b"]["u2"] == pytest.approx(2 / 3)
    assert result.reduction["d"] == {"u1": 4.0, "u2": 1.0}
    assert result.reduced == ["b"]
    assert result.middlebury == {"a": 2.5, "b": 2.0, "c": 3.0, "d": 2.5}
    assert result.interpretation == interpretation(WORKED_METHODS, [1, 1, 2, 1], ["b"])


def test_evaluate_models_keeps_input_order() -> None:
    order = [3, 2, 1, 0]
    names = [WORKED_METHODS[i] for i in order]
    result = evaluate_models(names, WORKED[order])
    assert result.methods == ["d", "c", "b", "a"]
    assert list(result.groups) == ["d", "c", "b", "a"]
    assert result.astar == ["d", "b", "a"]
    assert list(result.reduction) == ["d", "b", "a"]
    assert list(result.middlebury) == ["d", "c", "b", "a"]


def test_to_dict_is_plain_json() -> None:
    data = evaluate_models(WORKED_METHODS, WORKED).to_dict()
    assert set(data) == {"astar", "groups", "reduction", "reduced", "middlebury", "interpretation"}
    assert json.loads(json.dumps(data)) == data
    assert all(type(g) is int for g in data["groups"].values())
    assert all(type(r) is float for r in data["middlebury"].values())
    assert all(type(v) is float for pair in data["reduction"].values() for v in pair.values())
    assert data["astar"] == ["a", "b", "d"]
    assert data["reduced"] == ["b"]


def test_evaluate_models_single_method() -> None:
    result = evaluate_models(["only"], [[0.5, 2.0, 7.0]])
    assert result.groups == {"only": 1}
    assert result.astar == ["only"]
    assert result.reduced == ["only"]
    assert result.reduction == {"only": {"u1": 3.0, "u2": 0.0}}
    assert result.middlebury == {"only": 1.0}
    assert result.interpretation.startswith("A* = {only}: a single method of superior performance")


def test_evaluate_models_nan_counts_as_worst() -> None:
    result = evaluate_models(["x", "y"], [[math.nan, 1.0], [2.0, 1.0]])
    assert result.groups == {"x": 2, "y": 1}
    assert result.middlebury == {"x": 1.5, "y": 1.0}


@pytest.mark.parametrize(
    ("methods", "matrix", "message"),
    [
        (["a", "b"], [1.0, 2.0], "2-D"),
        (["a", "b"], [[1.0], [2.0], [3.0]], r"one row per method \(2\), got 3 rows"),
        (["a", "b"], np.zeros((2, 0)), "at least one objective"),
        (["a", "b", "a"], np.zeros((3, 1)), r"unique, got duplicates: \['a'\]"),
        ([], np.zeros((0, 1)), "at least one method"),
        ("ab", np.zeros((2, 1)), "list of names"),
        (["a", 2], np.zeros((2, 1)), "strings"),
        (["a", "b"], [["x"], ["y"]], "numeric"),
        (["a", "b"], [[1.0, 2.0], [1.0]], "numeric"),
    ],
)
def test_evaluate_models_validates(methods: object, matrix: object, message: str) -> None:
    with pytest.raises(ConfigurationError, match=message) as caught:
        evaluate_models(methods, matrix)  # type: ignore[arg-type]
    assert isinstance(caught.value, DispevalError)
    assert "\n" not in str(caught.value)


# --- properties --------------------------------------------------------------------------

values = st.one_of(st.integers(0, 3).map(float), st.just(math.nan))
matrices = st.tuples(st.integers(1, 8), st.integers(1, 4)).flatmap(
    lambda shape: hnp.arrays(np.float64, shape, elements=values)
)
PROPERTY = settings(max_examples=150, deadline=None)


def _brute_front(matrix: np.ndarray) -> list[bool]:
    n = len(matrix)
    return [not any(dominates(matrix[i], matrix[j]) for i in range(n) if i != j) for j in range(n)]


@PROPERTY
@given(matrices)
def test_groups_properties(matrix: np.ndarray) -> None:
    groups = astar_groups(matrix)
    n = len(matrix)
    assert groups.shape == (n,)
    top = int(groups.max())
    assert set(groups.tolist()) == set(range(1, top + 1))
    for j in range(n):
        for i in range(n):
            if groups[i] >= groups[j]:
                assert not dominates(matrix[i], matrix[j])
        if groups[j] > 1:
            assert any(
                dominates(matrix[i], matrix[j]) for i in range(n) if groups[i] == groups[j] - 1
            )


@PROPERTY
@given(matrices)
def test_front_matches_brute_force(matrix: np.ndarray) -> None:
    front = pareto_front(matrix)
    assert front.tolist() == _brute_front(matrix)
    assert np.array_equal(front, astar_groups(matrix) == 1)


@PROPERTY
@given(matrices)
def test_reduction_and_ranks_match_definitions(matrix: np.ndarray) -> None:
    finite = np.where(np.isnan(matrix), np.inf, matrix)
    n, m = finite.shape
    ranks = np.array(
        [[1 + np.sum(finite[:, k] < finite[j, k]) for k in range(m)] for j in range(n)]
    )
    assert middlebury_ranks(matrix).tolist() == pytest.approx(ranks.mean(axis=1).tolist())
    groups = astar_groups(matrix)
    for group in range(1, int(groups.max()) + 1):
        rows = finite[groups == group]
        reduction = front_reduction(rows)
        assert reduction.reduced.shape == (len(rows),)
        assert reduction.reduced.any()
        group_ranks = np.array(
            [[1 + np.sum(rows[:, k] < rows[j, k]) for k in range(m)] for j in range(len(rows))]
        )
        assert reduction.u1.tolist() == group_ranks.sum(axis=1).tolist()
        assert np.all((reduction.u2 >= 0) & (reduction.u2 <= m))


@PROPERTY
@given(matrices)
def test_evaluate_models_properties(matrix: np.ndarray) -> None:
    names = [f"m{i}" for i in range(len(matrix))]
    result = evaluate_models(names, matrix)
    assert list(result.groups) == names
    assert result.astar == [name for name in names if result.groups[name] == 1]
    assert result.reduced
    assert set(result.reduced) <= set(result.astar)
    assert list(result.reduction) == result.astar
    assert json.loads(json.dumps(result.to_dict())) == result.to_dict()


@PROPERTY
@given(st.lists(st.tuples(st.integers(1, 4), st.integers(1, 4)), max_size=8))
def test_measure_consistency_properties(pairs: list[tuple[int, int]]) -> None:
    first = [a for a, _ in pairs]
    second = [b for _, b in pairs]
    value = measure_consistency(first, second)
    assert 0.0 <= value <= 1.0
    assert value == measure_consistency(second, first)
    assert measure_consistency(first, first) == 1.0


# --- sort-based non-dominated sorting against a brute-force peeling ----------------------


def _brute_groups(matrix: np.ndarray) -> list[int]:
    """A* Groups by definition: peel the non-dominated rows of what remains, pair by pair."""
    rows = [[math.inf if math.isnan(v) else float(v) for v in row] for row in matrix]

    def beats(a: list[float], b: list[float]) -> bool:
        pairs = list(zip(a, b, strict=True))
        return all(x <= y for x, y in pairs) and any(x < y for x, y in pairs)

    groups = [0] * len(rows)
    remaining = set(range(len(rows)))
    group = 0
    while remaining:
        group += 1
        front = {j for j in remaining if not any(beats(rows[i], rows[j]) for i in remaining)}
        for j in front:
            groups[j] = group
        remaining -= front
    return groups


# Heavy ties: few distinct values, signed zeros that must compare equal, NaN (= +inf) and +inf.
tied_values = st.sampled_from([0.0, -0.0, 1.0, 2.0, 2.5, math.nan, math.inf])
random_values = st.one_of(st.floats(0.0, 1e6), st.sampled_from([math.nan, math.inf, -0.0]))


@st.composite
def objective_matrices(draw: st.DrawFn) -> np.ndarray:
    """Random or tied matrices, often with duplicate rows drawn from a small pool."""
    n = draw(st.integers(1, 14))
    m = draw(st.sampled_from([1, 2, 2, 3, 4, 6]))
    elements = draw(st.sampled_from([tied_values, random_values]))
    pool = draw(hnp.arrays(np.float64, (draw(st.integers(1, n)), m), elements=elements))
    picks = draw(st.lists(st.integers(0, len(pool) - 1), min_size=n, max_size=n))
    return pool[picks]


@pytest.mark.parametrize("small_problem", [dominance.SMALL_PROBLEM, 0])
@settings(max_examples=300, deadline=None)
@given(matrix=objective_matrices())
def test_groups_match_brute_force_peeling(matrix: np.ndarray, small_problem: int) -> None:
    """Both paths: the dominance table for few methods and the compiled sorting (forced)."""
    expected = _brute_groups(matrix)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(dominance, "SMALL_PROBLEM", small_problem)
        assert astar_groups(matrix).tolist() == expected
        assert pareto_front(matrix).tolist() == [g == 1 for g in expected]
        names = [f"m{i}" for i in range(len(matrix))]
        result = evaluate_models(names, matrix)
        assert list(result.groups.values()) == expected


@pytest.mark.parametrize("small_problem", [dominance.SMALL_PROBLEM, 0])
def test_signed_zero_and_duplicates_tie(
    monkeypatch: pytest.MonkeyPatch, small_problem: int
) -> None:
    monkeypatch.setattr(dominance, "SMALL_PROBLEM", small_problem)
    matrix = [[0.0, 1.0, 2.0], [-0.0, 1.0, 2.0], [0.0, 1.0, 2.0], [0.0, 1.0, 3.0]]
    assert astar_groups(matrix).tolist() == [1, 1, 1, 2]
    assert astar_groups([[-0.0, 1.0], [0.0, 1.0], [0.0, 0.5]]).tolist() == [2, 2, 1]


def test_sweep_scale_groups_match_brute_force() -> None:
    """A few hundred correlated, rounded methods (many groups, ties and duplicate rows)."""
    rng = np.random.default_rng(11)
    for objectives in (2, 3, 12):
        quality = rng.gamma(2.0, 2.0, size=(300, 1))
        matrix = np.round(quality + rng.normal(0.0, 0.8, size=(300, objectives)), 0)
        matrix[rng.random(matrix.shape) < 0.02] = np.nan
        assert astar_groups(matrix).tolist() == _brute_groups(matrix)


def test_long_chains_and_many_groups() -> None:
    """More groups than the sorter's storage foresees at first (it grows)."""
    chain = np.arange(400, dtype=float)[::-1, None] * np.ones((1, 3))
    assert astar_groups(chain).tolist() == list(range(400, 0, -1))
    assert pareto_front(chain).tolist() == [False] * 399 + [True]
    pairs = np.column_stack([np.arange(300.0), np.arange(300.0)[::-1] % 7])
    assert astar_groups(pairs).tolist() == _brute_groups(pairs)
