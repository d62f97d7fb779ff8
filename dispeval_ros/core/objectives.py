"""From scores to the method × objective matrix that the models compare (METHOD.md §4)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from dispeval_ros.core import registry
from dispeval_ros.core.measures import (
    GT_FREE_MEASURES,
    GT_FREE_PREFIX,
    HIGHER_IS_BETTER,
    bad_threshold,
)
from dispeval_ros.core.temporal import PairScores, pair_bad_threshold
from dispeval_ros.core.timing import TIMING_MEASURES, Timing, is_timing_measure
from dispeval_ros.errors import ConfigurationError

if TYPE_CHECKING:  # (the residual's kernels are not imported to read its sums)
    from dispeval_ros.core.egomotion import TemporalSums

ScoreTable = Mapping[str, Mapping[str, float]]

#: The objectives the models compare where they are scored (METHOD.md §4).
DEFAULT_OBJECTIVE_MEASURES = registry.names(objective=True, needs=registry.NEEDS_GT)
#: The objective of ground-truth-free scores (without GT, or beside it when asked for).
(GT_FREE_OBJECTIVE,) = registry.names(objective=True, needs=registry.NEEDS_IMAGES)
#: :func:`default_objective_measures` in words, for the options' help.
DEFAULT_OBJECTIVES_TEXT = (
    "sze and bmpre where scored, else every GT measure scored but density; vpe without GT"
)


def default_objective_measures(scored: Sequence[str]) -> list[str]:
    """The objectives when none are named, following the measures ``scored``.

    SZE and BMPRE where scored; else every scored ground-truth measure but the
    higher-is-better ones (density: how much was delivered, not how well); without a
    ground-truth measure, vpe. So narrowing the measures never leaves an objective unscored.
    """
    preferred = [m for m in DEFAULT_OBJECTIVE_MEASURES if m in scored]
    if preferred:
        return preferred
    gt = [m for m in scored if m not in GT_FREE_MEASURES and m not in HIGHER_IS_BETTER]
    if gt:
        return gt
    return [GT_FREE_OBJECTIVE] if GT_FREE_OBJECTIVE in scored else list(scored)


def has_points(scores: Mapping[str, ScoreTable], criterion: str) -> bool:
    """Whether ``criterion`` holds a point for some method (``n`` > 0).

    A criterion without points (``boundary`` of KITTI's GT, which has no disparity jump) has
    no defined score: its ratios are undefined and its sums 0 for every method. It is never
    an objective (it would only add a column that cannot tell methods apart).
    """
    return any(float(table[criterion]["n"]) > 0 for table in scores.values() if criterion in table)


def objective_matrix(
    scores: Mapping[str, ScoreTable],
    measures: Sequence[str],
    criteria: Sequence[str] | None = None,
) -> tuple[list[str], list[str], np.ndarray]:
    """Methods, objective names (``criterion/measure``) and the matrix, all minimised.

    ``scores`` maps method → criterion → measure → value. ``criteria`` defaults to those of
    the first method; criteria without points (:func:`has_points`) are left out. Higher-is-
    better measures (density) are negated so that every objective is minimised.
    """
    methods = list(scores)
    if not methods:
        raise ConfigurationError("no method to compare")
    named = list(criteria) if criteria is not None else list(scores[methods[0]])
    chosen = [c for c in named if has_points(scores, c)]
    names = [f"{criterion}/{measure}" for criterion in chosen for measure in measures]
    matrix = np.empty((len(methods), len(names)), dtype=np.float64)
    for row, method in enumerate(methods):
        table = scores[method]
        column = 0
        for criterion in chosen:
            if criterion not in table:
                raise ConfigurationError(
                    f"method '{method}' has no scores for criterion '{criterion}'"
                )
            for measure in measures:
                value = float(table[criterion][measure])
                matrix[row, column] = -value if measure in HIGHER_IS_BETTER else value
                column += 1
    return methods, names, matrix


def is_pair_measure(name: str) -> bool:
    """Whether ``name`` is a temporal pair measure (``tepe``, ``tepe_r``, ``tepe_bad_X``)."""
    known = name in registry.PAIR_BY_NAME and name not in registry.PAIR_FAMILIES
    return known or pair_bad_threshold(name) is not None


def split_pair_measures(measures: Sequence[str]) -> tuple[list[str], list[str]]:
    """The other measures and the temporal pair measures (``tepe``…) of ``measures``."""
    return (
        [m for m in measures if not is_pair_measure(m)],
        [m for m in measures if is_pair_measure(m)],
    )


def pair_objectives(
    pairs: Mapping[str, PairScores] | None,
    sequence: str,
    methods: Sequence[str],
    measures: Sequence[str],
) -> tuple[list[str], np.ndarray]:
    """The temporal objectives of a sequence: ``criterion/measure @sequence`` per criterion.

    Like the timing objectives (:func:`timing_objectives`), each method's own pairs pooled by
    their sums (the measures are means, which fewer pairs do not lower); only criteria with a
    pixel pair for some method. Without pairs recorded, or a method without a pair, one line.
    """
    if not measures:
        return [], np.empty((len(methods), 0))
    if not pairs:
        raise ConfigurationError(
            f"objective measure(s) {', '.join(measures)}: no temporal pair recorded for "
            f"sequence {sequence} (run with --temporal, on a sequence of two frames or more)"
        )
    missing = [m for m in methods if m not in pairs]
    if missing:
        raise ConfigurationError(
            f"objective measure(s) {', '.join(measures)}: {', '.join(missing)} has no pair of "
            f"consecutive frames in sequence {sequence}"
        )
    first = pairs[methods[0]]
    unknown = [m for m in measures if m not in first.measures]
    if unknown:
        raise ConfigurationError(
            f"objective measure(s) {', '.join(unknown)}: not among the pair measures scored "
            f"({', '.join(first.measures)})"
        )
    criteria = [c for c in first.criteria if any(p[c]["n_pair"] > 0 for p in pairs.values())]
    names = [f"{c}/{m} @{sequence}" for c in criteria for m in measures]
    block = np.array(
        [[pairs[method][c][m] for c in criteria for m in measures] for method in methods],
        dtype=np.float64,
    ).reshape(len(methods), len(names))
    return names, block


def split_timing_measures(measures: Sequence[str]) -> tuple[list[str], list[str]]:
    """The per-criterion measures and the timing measures (``latency_p95``…) of ``measures``."""
    return (
        [m for m in measures if not is_timing_measure(m)],
        [m for m in measures if is_timing_measure(m)],
    )


def timing_objectives(
    timing: Mapping[str, Timing] | None,
    sequence: str,
    methods: Sequence[str],
    measures: Sequence[str],
) -> tuple[list[str], np.ndarray]:
    """The timing objectives of a sequence: one column per measure (``name @sequence``).

    A timing measure is one value per method and sequence, not per criterion (see
    :mod:`~dispeval_ros.core.timing`), so it adds one column per sequence beside the
    criteria's, whatever the granularity of those; rates (higher is better) are negated.
    Without recorded latency, or with a value undefined (too few arrivals), one line.
    """
    if not measures:
        return [], np.empty((len(methods), 0))
    if not timing:
        raise ConfigurationError(
            f"objective measure(s) {', '.join(measures)}: no latency recorded for sequence "
            f"{sequence} (results written before arrival times were, or scored from files)"
        )
    block = np.empty((len(methods), len(measures)), dtype=np.float64)
    for row, method in enumerate(methods):
        for column, name in enumerate(measures):
            method_timing = timing.get(method)
            value = method_timing.value(name) if method_timing else float("nan")
            if not np.isfinite(value):
                frames = method_timing.frames if method_timing else 0
                raise ConfigurationError(
                    f"objective measure {name} ({TIMING_MEASURES[name].text}) is undefined for "
                    f"{method} over sequence {sequence}: {frames} estimate(s) arrived, too few "
                    "or too close together; choose another timing measure"
                )
            block[row, column] = -value if TIMING_MEASURES[name].higher_is_better else value
    return [f"{name} @{sequence}" for name in measures], block


_EGOMOTION = "egomotion_"
#: The ego-motion residual's values that can be objectives (lower is better): objective measure
#: → (its key in :meth:`TemporalSums.summary`, what it is). Temporal noise measured without
#: ground truth, not accuracy: their objectives are on ``gtfree:`` criteria.
EGOMOTION_OBJECTIVES: dict[str, tuple[str, str]] = {
    f"{_EGOMOTION}mean_abs": ("mean_abs", "mean |residual| in px"),
    f"{_EGOMOTION}rms": ("rms", "rms residual in px"),
    f"{_EGOMOTION}bad_X": ("bad_X", "% of residuals above X px, X a scored threshold"),
}
#: :data:`EGOMOTION_OBJECTIVES` in words, for the options' help.
EGOMOTION_OBJECTIVES_TEXT = "; ".join(
    f"{name} ({text})" for name, (_, text) in EGOMOTION_OBJECTIVES.items()
)


def egomotion_key(name: str) -> str | None:
    """The :meth:`TemporalSums.summary` key of ego-motion objective ``name``, else None."""
    if name in EGOMOTION_OBJECTIVES and not name.endswith("_X"):
        return EGOMOTION_OBJECTIVES[name][0]
    if not name.startswith(_EGOMOTION):
        return None
    threshold = bad_threshold(name[len(_EGOMOTION) :])
    return None if threshold is None else f"bad_{threshold:g}"


def is_egomotion_measure(name: str) -> bool:
    """Whether ``name`` is an ego-motion residual objective (``egomotion_rms``…)."""
    return egomotion_key(name) is not None


def split_egomotion_measures(measures: Sequence[str]) -> tuple[list[str], list[str]]:
    """The other measures and the ego-motion residual measures of ``measures``."""
    return (
        [m for m in measures if not is_egomotion_measure(m)],
        [m for m in measures if is_egomotion_measure(m)],
    )


def egomotion_objectives(
    motion: Mapping[str, tuple[int, TemporalSums]] | None,
    sequence: str,
    methods: Sequence[str],
    measures: Sequence[str],
) -> tuple[list[str], np.ndarray]:
    """The ego-motion residual objectives: ``gtfree:criterion/measure @sequence``, minimised.

    ``motion``: per method its pairs and their pooled sums (the residual is a mean over
    the counted pixels, which fewer pairs do not lower). Only criteria where some method
    counted a pixel; without residuals recorded, a method without one, a threshold not
    scored or a value undefined for one method, one line.
    """
    if not measures:
        return [], np.empty((len(methods), 0))
    what = f"objective measure(s) {', '.join(measures)}"
    if not motion:
        raise ConfigurationError(
            f"{what}: no ego-motion residual recorded for sequence {sequence} (run with "
            "--egomotion, on a sequence of two frames or more with /tf)"
        )
    missing = [m for m in methods if m not in motion]
    if missing:
        raise ConfigurationError(
            f"{what}: {', '.join(missing)} has no ego-motion pair in sequence {sequence}"
        )
    first = motion[methods[0]][1]
    keys = [str(egomotion_key(m)) for m in measures]
    scored = first.summary(first.criteria[0])
    unknown = [m for m, key in zip(measures, keys, strict=True) if key not in scored]
    if unknown:
        levels = ", ".join(f"{t:g}" for t in first.thresholds)
        raise ConfigurationError(
            f"objective measure(s) {', '.join(unknown)}: the ego-motion residual was scored "
            f"at thresholds {levels} px only"
        )
    criteria = [
        c for c in first.criteria if any(s.column(c, "n_residual") > 0 for _, s in motion.values())
    ]
    block = np.empty((len(methods), len(criteria) * len(keys)), dtype=np.float64)
    for row, method in enumerate(methods):
        sums = motion[method][1]
        values = [sums.summary(c)[key] for c in criteria for key in keys]
        block[row] = values
        if not np.isfinite(block[row]).all():
            raise ConfigurationError(
                f"{what}: {method} has no residual counted on some criterion of sequence "
                f"{sequence} ({', '.join(criteria)}); choose other criteria"
            )
    names = [f"{GT_FREE_PREFIX}{c}/{m} @{sequence}" for c in criteria for m in measures]
    return names, block
