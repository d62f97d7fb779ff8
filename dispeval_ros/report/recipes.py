"""The measures as the report page's recipes: the registry written as data the script interprets.

The browser derives every measure from the rows of sums exactly as
:func:`dispeval_ros.core.measures.measure_from_sums` does, from the same declaration
(:data:`dispeval_ros.core.registry.MEASURES`): no second table of fields and scales.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from dispeval_ros.core import registry
from dispeval_ros.core.measures import bad_threshold, measure_unit, quantile_level
from dispeval_ros.errors import ConfigurationError

_NONE = -1
"""A recipe's ``num`` / ``den`` when it reads no field."""


def _registered(name: str) -> registry.Measure | None:
    """The registry entry of ``name`` (its family's for ``bad_X`` / ``aNN``), else None."""
    if bad_threshold(name) is not None:
        return registry.BY_NAME["bad_X"]
    if quantile_level(name) is not None:
        return registry.BY_NAME["aNN"]
    measure = registry.BY_NAME.get(name)
    return measure if measure is not None and measure is not registry.POINTS else None


def _field(name: str | None) -> int:
    return _NONE if name is None else registry.field_index(name)


def measure_recipe(name: str, thresholds: np.ndarray) -> dict[str, Any]:
    """How the browser derives measure ``name`` from a row of sums (or reads it stored).

    Kinds: ``ratio`` (``scale * sums[num] / sums[den]``, NaN unless ``sums[den] > 0``),
    ``sqrt_ratio`` (the root of that ratio: the registry's scale, outside the root, is squared
    inside it), ``total`` (``sums[num]``) and ``stored`` (a per-frame quantile; not summable,
    NaN over sequences). ``higher`` marks higher-is-better measures, negated in objectives.
    """
    measure = _registered(name)
    if measure is None:
        raise ConfigurationError(f"measure '{name}' is not known to the report")
    recipe: dict[str, Any] = {
        "name": name,
        "higher": measure.direction == registry.HIGHER,
        "unit": measure_unit(name),
    }
    if measure_unit(name, relative=True) != recipe["unit"]:  # SZE without a camera
        recipe["relative_unit"] = measure_unit(name, relative=True)
    num = _field(measure.num)
    if measure.name == "bad_X":
        hits = np.flatnonzero(np.asarray(thresholds)[1:] == bad_threshold(name))
        if hits.size == 0:
            raise ConfigurationError(f"measure '{name}' has no threshold column in the results")
        num = registry.field_index("bad_count_0") + int(hits[0]) + 1
    scale = measure.scale * measure.scale if measure.kind == registry.SQRT_RATIO else measure.scale
    recipe.update(kind=measure.kind, num=num, den=_field(measure.den), scale=float(scale))
    return recipe


def recipe_values(
    recipe: Mapping[str, Any], sums: np.ndarray, stored: np.ndarray | None = None
) -> np.ndarray:
    """Vectorised :func:`measure_recipe` evaluation over rows of sums (``(..., fields)``)."""
    kind = recipe["kind"]
    shape = sums.shape[:-1]
    if kind == "stored":
        return np.full(shape, np.nan) if stored is None else np.asarray(stored, np.float64)
    numerator = sums[..., recipe["num"]]
    if kind == "total":
        return numerator.astype(np.float64, copy=True)
    denominator = sums[..., recipe["den"]]
    result = np.full(shape, np.nan)
    ok = denominator > 0
    result[ok] = recipe["scale"] * numerator[ok] / denominator[ok]
    if kind == "sqrt_ratio":
        result = np.sqrt(result)
    return result
