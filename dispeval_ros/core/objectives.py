"""From scores to the method × objective matrix that the models compare (METHOD.md §4)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from dispeval_ros.core.measures import HIGHER_IS_BETTER
from dispeval_ros.errors import ConfigurationError

ScoreTable = Mapping[str, Mapping[str, float]]


def objective_matrix(
    scores: Mapping[str, ScoreTable],
    measures: Sequence[str],
    criteria: Sequence[str] | None = None,
) -> tuple[list[str], list[str], np.ndarray]:
    """Methods, objective names (``criterion/measure``) and the matrix, all minimised.

    ``scores`` maps method → criterion → measure → value. ``criteria`` defaults to those of
    the first method. Higher-is-better measures (density) are negated so that every
    objective is minimised.
    """
    methods = list(scores)
    if not methods:
        raise ConfigurationError("no method to compare")
    chosen = list(criteria) if criteria is not None else list(scores[methods[0]])
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
