"""Evaluation models that compare methods by their objective vectors (METHOD.md §5).

A method is a row of a ``(methods, objectives)`` matrix; every objective is minimised. The
models need no weights: dominance (``a ≺ b``), the Pareto front A*, the A* Groups (fronts peeled
one after another), the front reduction that picks within a group by the ``(u1, u2)`` pair, the
Middlebury average rank (for comparison) and the consistency of two groupings.

Missing values: a NaN objective value is treated as ``+inf``, the worst possible value (a method
that could not be scored on an objective must never look good on it). Two ``+inf`` values tie.
``-inf`` is rejected: measures are non-negative, so it can only be a bug upstream. In the front
reduction's ``u2`` an infinite value is handled as the limit of a very large number: it scores
1 on that objective, every finite value of the same objective 0 (and all-infinite gives 0, as
``max = min``).

Everything here is deterministic. Dominance works on per-objective ranks with a sort-based
non-dominated sorting (:mod:`dispeval_ros.core.dominance`): sweeps of thousands of methods
(every parameter set of a stereo algorithm is a method) take milliseconds, never an
``N × N`` matrix.
"""

from __future__ import annotations

import bisect
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from dispeval_ros.core import dominance
from dispeval_ros.errors import ConfigurationError

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int_]
GroupsLike = Mapping[str, int] | npt.ArrayLike

# Two u2 sums closer than this are the same value: different summation orders of the same
# fractions must not create a dominance that does not exist mathematically.
_U2_TOLERANCE = 1e-9


def _as_matrix(matrix: npt.ArrayLike, what: str = "objective matrix") -> FloatArray:
    """Return ``matrix`` as a 2-D float array with NaN replaced by ``+inf``.

    One conversion for every public function, so all of them agree on what NaN means.
    """
    try:
        array = np.array(matrix, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ConfigurationError(
            f"{what} must be numeric (methods × objectives), got {type(matrix).__name__}: {error}"
        ) from None
    if array.ndim != 2:
        raise ConfigurationError(
            f"{what} must be 2-D (methods × objectives), got {array.ndim}-D shape {array.shape}"
        )
    if np.any(np.isneginf(array)):
        raise ConfigurationError(f"{what} must not contain -inf (objectives are minimised)")
    array[np.isnan(array)] = np.inf
    return array


def _as_vector(values: npt.ArrayLike, what: str) -> FloatArray:
    """Return one objective vector as a 1-D float array (NaN → ``+inf``)."""
    try:
        vector = np.array(values, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ConfigurationError(f"{what} must be numeric, got {values!r}: {error}") from None
    if vector.ndim != 1:
        raise ConfigurationError(f"{what} must be 1-D, got shape {vector.shape}")
    return _as_matrix(vector[None, :], what)[0]


def dominates(a: npt.ArrayLike, b: npt.ArrayLike) -> bool:
    """Tell whether ``a ≺ b``: no worse on every objective and better on at least one."""
    va = _as_vector(a, "first objective vector")
    vb = _as_vector(b, "second objective vector")
    if va.shape != vb.shape:
        raise ConfigurationError(
            f"objective vectors must have the same length, got {va.size} and {vb.size}"
        )
    return bool(np.all(va <= vb) and np.any(va < vb))


def _column_order(values: FloatArray) -> tuple[IntArray, FloatArray]:
    """Sort each objective once: per objective (rows of the result) the method order and values.

    Objective-major, so every sort runs over contiguous memory.
    """
    by_objective = np.ascontiguousarray(values.T)
    order = np.argsort(by_objective, axis=1)
    return order, np.take_along_axis(by_objective, order, axis=1)


def _unsort(sorted_ranks: npt.NDArray[Any], order: IntArray) -> npt.NDArray[Any]:
    """Ranks back in method order, transposed to ``(methods, objectives)``."""
    ranks = np.empty_like(sorted_ranks)
    np.put_along_axis(ranks, order, sorted_ranks, axis=1)
    return ranks.T


def _dense_ranks(order: IntArray, ordered: FloatArray) -> npt.NDArray[np.int32]:
    """Rank each objective 0, 1, 2, ... by value, equal values sharing a rank (``-0.0 == 0.0``)."""
    m, n = ordered.shape
    sorted_ranks = np.zeros((m, n), dtype=np.int32)
    np.cumsum(ordered[:, 1:] != ordered[:, :-1], axis=1, out=sorted_ranks[:, 1:])
    return np.ascontiguousarray(_unsort(sorted_ranks, order))


def _competition_from_order(order: IntArray, ordered: FloatArray) -> IntArray:
    """Rank each objective, 1 = lowest, ties sharing the lowest rank ("1, 1, 3")."""
    m, n = ordered.shape
    starts = np.ones((m, n), dtype=np.bool_)
    starts[:, 1:] = ordered[:, 1:] != ordered[:, :-1]
    positions = np.arange(1, n + 1, dtype=np.int_)[None, :]
    sorted_ranks = np.maximum.accumulate(np.where(starts, positions, 0), axis=1)
    return _unsort(sorted_ranks, order)


def _fronts(dense: npt.NDArray[np.int32], first_only: bool) -> IntArray:
    """A* Group of every row of dense ranks (``first_only``: 1 for A*, 2 for the rest)."""
    n, m = dense.shape
    if n == 0:
        return np.zeros(0, dtype=np.int_)
    if m == 1:
        column = dense[:, 0].astype(np.int_) + 1
        return np.minimum(column, 2) if first_only else column
    if n <= dominance.SMALL_PROBLEM:
        return dominance.fronts_small(dense, first_only).astype(np.int_)
    if m == 2:
        first = np.ascontiguousarray(dense[:, 0])
        second = np.ascontiguousarray(dense[:, 1])
        return dominance.fronts_two(first, second, first_only).astype(np.int_)
    return dominance.fronts_many(np.ascontiguousarray(dense), first_only).astype(np.int_)


def _groups_of(values: FloatArray, first_only: bool) -> IntArray:
    if values.shape[0] == 0:
        return np.zeros(0, dtype=np.int_)
    return _fronts(_dense_ranks(*_column_order(values)), first_only)


def pareto_front(matrix: npt.ArrayLike) -> BoolArray:
    """Mark the methods (rows) no other method dominates: A*, the Pareto front."""
    front: BoolArray = _groups_of(_as_matrix(matrix), first_only=True) == 1
    return front


def astar_groups(matrix: npt.ArrayLike) -> IntArray:
    """Give each method its A* Group (1 = the front, 2 = the front of the rest, ...).

    Non-dominated sorting on per-objective ranks (see :mod:`dispeval_ros.core.dominance`):
    ``O(N log N)`` for two objectives and never an ``N × N`` matrix.
    """
    return _groups_of(_as_matrix(matrix), first_only=False)


def _competition_ranks(values: FloatArray) -> IntArray:
    """Rank each column, 1 = lowest, ties sharing the lowest rank ("1, 1, 3")."""
    n, m = values.shape
    if n == 0:
        return np.zeros((0, m), dtype=np.int_)
    return _competition_from_order(*_column_order(values))


def _normalised(values: FloatArray) -> FloatArray:
    """Scale each column to ``(f − min)/(max − min)``; 0 where ``max = min``.

    An infinite value scores 1 and the finite values of its column 0: the limit of the formula
    as that value grows without bound.
    """
    n, m = values.shape
    if n == 0:
        return np.zeros((0, m), dtype=np.float64)
    low = values.min(axis=0)
    high = values.max(axis=0)
    result = np.zeros((n, m), dtype=np.float64)
    finite_range = np.isfinite(high) & (high > low)
    if finite_range.any():
        cols = values[:, finite_range]
        span = high[finite_range] - low[finite_range]
        result[:, finite_range] = (cols - low[finite_range]) / span
    infinite_top = np.isinf(high) & (high > low)
    result[:, infinite_top] = np.isinf(values[:, infinite_top]).astype(np.float64)
    return result


def _snap(values: FloatArray, tolerance: float) -> FloatArray:
    """Merge values that differ by at most ``tolerance`` from their sorted neighbour."""
    if values.size == 0:
        return values.copy()
    order = np.argsort(values, kind="stable")
    ordered = values[order]
    starts = np.ones(values.size, dtype=np.bool_)
    starts[1:] = np.diff(ordered) > tolerance
    cluster_first = np.maximum.accumulate(np.where(starts, np.arange(values.size), 0))
    snapped = np.empty_like(values)
    snapped[order] = ordered[cluster_first]
    return snapped


@dataclass(frozen=True)
class Reduction:
    """Front reduction of one group: the ``(u1, u2)`` pair of each row and the chosen rows."""

    u1: FloatArray
    u2: FloatArray
    reduced: BoolArray


def front_reduction(matrix: npt.ArrayLike) -> Reduction:
    """Choose within the rows given (one group) without weights, by the front of ``(u1, u2)``.

    ``u1`` sums the competition ranks within the rows, ``u2`` the min-max normalised values
    within the rows. ``u2`` sums that agree to within 1e-9 count as equal when comparing, so
    rounding in the sums cannot make one method dominate another.
    """
    values = _as_matrix(matrix)
    u1 = _competition_ranks(values).sum(axis=1).astype(np.float64)
    u2 = _normalised(values).sum(axis=1)
    pairs = np.column_stack([u1, _snap(u2, _U2_TOLERANCE)])
    return Reduction(u1=u1, u2=u2, reduced=pareto_front(pairs))


def middlebury_ranks(matrix: npt.ArrayLike) -> FloatArray:
    """Average each method's competition rank over the objectives (Middlebury's table order)."""
    values = _as_matrix(matrix)
    n, m = values.shape
    if m == 0:
        return np.full(n, np.nan)
    return _competition_ranks(values).mean(axis=1)


def _groups_arrays(groups_a: GroupsLike, groups_b: GroupsLike) -> tuple[IntArray, IntArray]:
    """Align two groupings: arrays by position, mappings by method name."""
    if isinstance(groups_a, Mapping) or isinstance(groups_b, Mapping):
        if not (isinstance(groups_a, Mapping) and isinstance(groups_b, Mapping)):
            raise ConfigurationError(
                "groupings must both be method→group mappings or both be arrays, got "
                f"{type(groups_a).__name__} and {type(groups_b).__name__}"
            )
        if set(groups_a) != set(groups_b):
            only = sorted(set(groups_a) ^ set(groups_b))
            raise ConfigurationError(
                f"groupings must name the same methods, got methods in only one: {only}"
            )
        names = list(groups_a)
        return (
            np.array([groups_a[name] for name in names], dtype=np.int_),
            np.array([groups_b[name] for name in names], dtype=np.int_),
        )
    first = np.asarray(groups_a, dtype=np.int_).ravel()
    second = np.asarray(groups_b, dtype=np.int_).ravel()
    if first.shape != second.shape:
        raise ConfigurationError(
            f"groupings must cover the same methods, got {first.size} and {second.size} groups"
        )
    return first, second


def measure_consistency(groups_a: GroupsLike, groups_b: GroupsLike) -> float:
    """Share of method pairs whose A* Groups relation agrees between two groupings.

    The relation of a pair is "same group", "first in a better group" or "first in a worse
    group"; two measures are consistent on a pair when they give the same relation. Groupings
    are arrays in the same method order, or mappings method → group. Fewer than two methods
    give 1.0 (nothing disagrees).

    Agreeing pairs are those tied in both groupings plus the concordant ones (better in both),
    counted by a sweep in O(N log N)-ish time and O(N) memory: sweeps of 10⁴ methods have 5·10⁷
    pairs, too many to list.
    """
    first, second = _groups_arrays(groups_a, groups_b)
    n = first.size
    if n < 2:
        return 1.0
    _, tied = np.unique(np.stack([first, second], axis=1), axis=0, return_counts=True)
    agreeing = int((tied * (tied - 1) // 2).sum())
    order = np.lexsort((second, first))
    by_first, by_second = first[order].tolist(), second[order].tolist()
    below: list[Any] = []  # second-grouping values of methods in a strictly better first group
    start = 0
    while start < n:
        stop = start
        while stop < n and by_first[stop] == by_first[start]:
            stop += 1
        agreeing += sum(bisect.bisect_left(below, value) for value in by_second[start:stop])
        for value in by_second[start:stop]:
            bisect.insort(below, value)
        start = stop
    return agreeing / (n * (n - 1) / 2)


def _join(names: Sequence[str]) -> str:
    return ", ".join(names)


def interpretation(methods: Sequence[str], groups: GroupsLike, reduced_names: Sequence[str]) -> str:
    """Say in plain English what the A* Groups and the front reduction found (METHOD.md §5).

    One line for A*, one per further group, one for the reduced set of group 1. ``groups`` is
    aligned with ``methods`` or maps method → group; names are listed in ``methods`` order.
    """
    if isinstance(groups, Mapping):
        numbers = [int(groups[name]) for name in methods]
    else:
        numbers = [int(g) for g in np.asarray(groups, dtype=np.int_).ravel()]
    if len(numbers) != len(methods):
        raise ConfigurationError(
            f"need one group per method, got {len(numbers)} groups for {len(methods)} methods"
        )
    if not numbers:
        return "No methods were evaluated."
    lines: list[str] = []
    for group in sorted(set(numbers)):
        members = [name for name, g in zip(methods, numbers, strict=True) if g == group]
        if group == 1:
            if len(members) == 1:
                lines.append(
                    f"A* = {{{members[0]}}}: a single method of superior performance "
                    "(it dominates every other method)."
                )
            else:
                lines.append(
                    f"A* = {{{_join(members)}}}: a set of methods of comparable performance "
                    "(mutually incomparable; every method outside A* is dominated by at least "
                    "one of them)."
                )
        elif len(members) == 1:
            lines.append(
                f"Group {group}: a single method: {members[0]} (dominated by at least one "
                f"method of group {group - 1})."
            )
        else:
            lines.append(
                f"Group {group}: {len(members)} methods of comparable performance: "
                f"{_join(members)} (mutually incomparable; each dominated by at least one "
                f"method of group {group - 1})."
            )
    if reduced_names:
        wanted = set(reduced_names)
        unknown = sorted(wanted - set(methods))
        if unknown:
            raise ConfigurationError(f"reduced set must name evaluated methods, got {unknown}")
        chosen = [name for name in methods if name in wanted]
        if len(chosen) == 1:
            lines.append(
                f"Front reduction of A* (chosen without weights, by the (u1, u2) front): "
                f"{chosen[0]}."
            )
        else:
            lines.append(
                f"Front reduction of A* (chosen without weights, by the (u1, u2) front): "
                f"{_join(chosen)} (incomparable in (u1, u2))."
            )
    return "\n".join(lines)


@dataclass(frozen=True)
class ModelResult:
    """Everything the models say about one objective matrix, lists in input method order."""

    methods: list[str]
    groups: dict[str, int]
    astar: list[str]
    reduction: dict[str, dict[str, float]]
    reduced: list[str]
    middlebury: dict[str, float]
    interpretation: str

    def to_dict(self) -> dict[str, Any]:
        """Return the JSON-ready form (plain Python types only) the reports write."""
        return {
            "astar": [str(name) for name in self.astar],
            "groups": {str(name): int(g) for name, g in self.groups.items()},
            "reduction": {
                str(name): {key: float(value) for key, value in pair.items()}
                for name, pair in self.reduction.items()
            },
            "reduced": [str(name) for name in self.reduced],
            "middlebury": {str(name): float(rank) for name, rank in self.middlebury.items()},
            "interpretation": str(self.interpretation),
        }


def evaluate_models(methods: Sequence[str], matrix: npt.ArrayLike) -> ModelResult:
    """Run A*, A* Groups, the front reduction of group 1 and the Middlebury ranks.

    ``matrix`` has one row per method (in ``methods`` order) and one column per objective,
    all minimised; NaN counts as ``+inf`` (worst possible).
    """
    if isinstance(methods, str):
        raise ConfigurationError(f"methods must be a list of names, got the string {methods!r}")
    names = list(methods)
    for name in names:
        if not isinstance(name, str):
            raise ConfigurationError(f"method names must be strings, got {name!r}")
    if not names:
        raise ConfigurationError("expected at least one method to evaluate, got none")
    duplicates = sorted(name for name, count in Counter(names).items() if count > 1)
    if duplicates:
        raise ConfigurationError(f"method names must be unique, got duplicates: {duplicates}")
    values = _as_matrix(matrix)
    if values.shape[0] != len(names):
        raise ConfigurationError(
            f"objective matrix must have one row per method ({len(names)}), "
            f"got {values.shape[0]} rows"
        )
    if values.shape[1] == 0:
        raise ConfigurationError("objective matrix must have at least one objective, got 0")

    order, ordered = _column_order(values)  # each objective sorted once for groups and ranks
    groups = _fronts(_dense_ranks(order, ordered), first_only=False)
    in_front = groups == 1
    astar = [name for name, front in zip(names, in_front, strict=True) if front]
    reduction = front_reduction(values[in_front])
    reduced = [name for name, keep in zip(astar, reduction.reduced, strict=True) if keep]
    middlebury = _competition_from_order(order, ordered).mean(axis=1)
    return ModelResult(
        methods=names,
        groups={name: int(g) for name, g in zip(names, groups, strict=True)},
        astar=astar,
        reduction={
            name: {"u1": float(u1), "u2": float(u2)}
            for name, u1, u2 in zip(astar, reduction.u1, reduction.u2, strict=True)
        },
        reduced=reduced,
        middlebury={name: float(r) for name, r in zip(names, middlebury, strict=True)},
        interpretation=interpretation(names, groups, reduced),
    )
