"""Error measures derived from per-criterion sums (METHOD.md §3, §4).

Scoring accumulates sums (counts, error sums, squared sums, relative sums, depth terms, bad
counts) per criterion; every measure is derived from them here. Sequence-level scores are
therefore exact: sums of sums, never averages of per-frame means.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np

from dispeval_ros.core import kernels as k
from dispeval_ros.core import registry
from dispeval_ros.errors import ConfigurationError

DEFAULT_BAD_THRESHOLDS = (0.5, 2.0, 4.0)
DEFAULT_QUANTILES = (50, 90, 95, 99)


def _expanded(name: str) -> tuple[str, ...]:
    """A registry name as default measures: the families at their default thresholds / levels."""
    if name == "bad_X":
        return tuple(f"bad_{t:g}" for t in DEFAULT_BAD_THRESHOLDS)
    if name == "aNN":
        return tuple(f"a{q}" for q in DEFAULT_QUANTILES)
    return (name,)


DEFAULT_MEASURES = tuple(n for name in registry.names(default=True) for n in _expanded(name))
HIGHER_IS_BETTER = registry.names(direction=registry.HIGHER)
COUNT_MEASURES = ("n", "bmp_count")
"""Values that count points: integers wherever they are written out."""
_BAD = re.compile(r"^bad_(\d+(?:\.\d+)?)$")
_QUANTILE = re.compile(r"^a(\d{1,2}(?:\.\d+)?)$")


def bad_threshold(name: str) -> float | None:
    """The threshold of a ``bad_X`` measure name, else None."""
    match = _BAD.match(name)
    return float(match.group(1)) if match else None


def quantile_level(name: str) -> float | None:
    """The percentage of an ``aNN`` quantile measure name, else None."""
    match = _QUANTILE.match(name)
    if not match:
        return None
    level = float(match.group(1))
    return level if 0 < level < 100 else None


def measure_unit(name: str, relative: bool = False) -> str:
    """The unit a measure's values are in, for tables, plots and reports ("" if none known).

    ``relative``: SZE computed without a camera (``f·B := 1``), so not in metres.
    """
    if name in ("sze", "sze_mean") and relative:
        return "relative (no camera)"
    if bad_threshold(name) is not None:
        return "%"
    if quantile_level(name) is not None:
        return "px"
    measure = registry.BY_NAME.get(name)
    return measure.unit if measure is not None else ""


def parse_measures(names: Iterable[str] | None) -> tuple[str, ...]:
    """Validate measure names (``bad_X`` and ``aNN`` take any threshold / level)."""
    if names is None:
        return DEFAULT_MEASURES
    chosen: list[str] = []
    for name in names:
        if (
            name in _FROM_SUMS
            or bad_threshold(name) is not None
            or quantile_level(name) is not None
        ):
            if name not in chosen:
                chosen.append(name)
            continue
        raise ConfigurationError(
            f"unknown measure '{name}'; known: "
            f"{', '.join((*DEFAULT_MEASURES, *DEPTH_MEASURES, *GT_FREE_MEASURES))} "
            "(bad_X for any threshold X, aNN for any quantile NN)"
        )
    if not chosen:
        raise ConfigurationError("no measure chosen")
    return tuple(chosen)


SEQUENCE_MEASURES = tuple(m for m in DEFAULT_MEASURES if quantile_level(m) is None)
"""Default for sequences and live streams: quantiles are neither summable over frames nor cheap."""


def thresholds_for(measures: Sequence[str], delta: float) -> np.ndarray:
    """The kernel's threshold vector: δ first, then each ``bad_X`` threshold, padded with inf."""
    extra = sorted({t for t in (bad_threshold(m) for m in measures) if t is not None})
    if len(extra) > k.MAX_THRESHOLDS - 1:
        raise ConfigurationError(
            f"at most {k.MAX_THRESHOLDS - 1} bad_X thresholds at once, got {len(extra)}"
        )
    values = [float(delta), *extra]
    return np.array(values + [math.inf] * (k.MAX_THRESHOLDS - len(values)), dtype=np.float64)


FIELDS = k.FIELD_COUNT
SUM_FIELDS = registry.SUM_FIELDS
"""Names of the accumulator columns (declared in :mod:`dispeval_ros.core.registry`)."""

GT_FREE_MEASURES = registry.names(needs=registry.NEEDS_IMAGES)
"""Measures that need no ground truth (view-prediction error, left-right inconsistency): scored
on the ``gtfree:`` criteria only, never objectives beside GT measures unless asked."""
GT_FREE_PREFIX = "gtfree:"
"""Criteria scored without ground truth carry this prefix wherever they appear."""


def applies(measure: str, criterion: str) -> bool:
    """Whether a measure is defined on a criterion.

    GT-free measures on ``gtfree:`` criteria only, GT measures on GT criteria only
    (``density`` and ``n`` on both).
    """
    needs = registry.BY_NAME[measure].needs if measure in registry.BY_NAME else registry.NEEDS_GT
    if needs == registry.NEEDS_NONE:
        return True
    return (needs == registry.NEEDS_IMAGES) == criterion.startswith(GT_FREE_PREFIX)


DEPTH_MEASURES = registry.names(family="depth")
"""Depth-domain measures (metres, or the camera's unit; ``irmse`` in 1/km as KITTI's depth
devkit). Not in the defaults of disparity GT (they add columns to every table); the default
for LiDAR GT, whose users think in metres."""


DEPTH_FIELDS = tuple(registry.field_index(name) for name in registry.CAMERA_FIELDS)
"""The sums that need the camera (f·B): SZE and the depth-domain measures."""


def _ratio(numerator: float, denominator: float, scale: float = 1.0) -> float:
    return scale * numerator / denominator if denominator > 0 else math.nan


_Sums = np.ndarray | Sequence[float]
"""One criterion's accumulator row (an array, or the same values as a list)."""


def _mean(field: int, scale: float = 1.0) -> Callable[[_Sums], float]:
    return lambda sums: _ratio(sums[field], sums[k.FIELD_EVAL], scale)


def from_registry(
    measure: registry.Measure, index: Callable[[str], int] = registry.field_index
) -> Callable[[_Sums], float]:
    """The derivation the registry declares for ``measure`` (a fixed-field one).

    ``index`` places its fields in a row of sums (the pair measures have their own columns).
    """
    assert measure.num is not None
    num = index(measure.num)
    if measure.kind == registry.TOTAL:
        return lambda sums: float(sums[num])
    assert measure.den is not None
    den = index(measure.den)
    scale = measure.scale
    if measure.kind == registry.SQRT_RATIO:
        return lambda sums: scale * math.sqrt(_ratio(sums[num], sums[den]))
    return lambda sums: _ratio(sums[num], sums[den], scale)


_FROM_SUMS: dict[str, Callable[[_Sums], float]] = {
    m.name: from_registry(m)
    for m in registry.MEASURES
    if m.kind != registry.STORED and m.name not in registry.FAMILIES
}
"""The measures of fixed fields, from the registry (``bad_X``, ``aNN``: see :func:`_derivation`)."""


def measure_from_sums(name: str, sums: _Sums, thresholds: np.ndarray) -> float:
    """One measure of one criterion from its accumulated sums (``nan`` where undefined)."""
    return float(_derivation(name, tuple(thresholds.tolist()))(sums))


@functools.lru_cache(maxsize=256)
def _derivation(name: str, thresholds: tuple[float, ...]) -> Callable[[_Sums], float]:
    """How ``name`` is computed from a row of sums with these bad-x thresholds."""
    derive = _FROM_SUMS.get(name)
    if derive is not None:
        return derive
    threshold = bad_threshold(name)
    if threshold is not None:
        return _mean(k.FIELD_BAD + thresholds.index(threshold, 1), 100.0)
    raise ConfigurationError(f"measure '{name}' is not derived from sums")


_FROM_QUANTILES = None
"""In :func:`_row_recipe`: the measure is a quantile (not derived from sums)."""


@functools.lru_cache(maxsize=64)
def _row_recipe(
    measures: tuple[str, ...], thresholds: tuple[float, ...], gt_free: bool
) -> tuple[tuple[str, Callable[[_Sums], float] | float | None], ...]:
    """Per measure of a criterion's row: its derivation, :data:`_FROM_QUANTILES` or nan.

    Nan where the measure does not apply (``gt_free``: the criterion is a ``gtfree:`` one).
    """
    criterion = GT_FREE_PREFIX if gt_free else ""
    recipe: list[tuple[str, Callable[[_Sums], float] | float | None]] = []
    for name in measures:
        if not applies(name, criterion):
            recipe.append((name, math.nan))
        elif quantile_level(name) is not None:
            recipe.append((name, _FROM_QUANTILES))
        else:
            recipe.append((name, _derivation(name, thresholds)))
    return tuple(recipe)


class ByCriterion(Mapping[str, Mapping[str, float]]):
    """A mapping criterion → measure → value over the ``criteria`` it holds, in their order."""

    criteria: tuple[str, ...]
    thresholds: np.ndarray

    def __iter__(self) -> Iterator[str]:
        return iter(self.criteria)

    def __len__(self) -> int:
        return len(self.criteria)

    def __contains__(self, criterion: object) -> bool:
        return criterion in self.criteria


_Combinable = TypeVar("_Combinable", bound=ByCriterion)


def first_of_combinable(parts: Sequence[_Combinable], what: str) -> _Combinable:
    """The first of ``parts`` once all share its criteria and thresholds (else one line)."""
    if not parts:
        raise ConfigurationError(f"no {what} to combine")
    first = parts[0]
    for part in parts[1:]:
        if part.criteria != first.criteria or not np.array_equal(part.thresholds, first.thresholds):
            raise ConfigurationError(f"cannot combine {what} of different criteria or thresholds")
    return first


@dataclass
class Scores(ByCriterion):
    """Scores of one method on one frame (or summed over frames), by criterion.

    ``scores[criterion][measure]``; ``scores[criterion]["n"]`` is the number of points.
    ``sums`` (criteria × fields) is what sequences add up. ``relative`` is True when no
    camera was known, so SZE is in units of ``f·B = 1``.
    """

    criteria: tuple[str, ...]
    measures: tuple[str, ...]
    sums: np.ndarray
    thresholds: np.ndarray
    quantiles: dict[str, dict[str, float]] = field(default_factory=dict)
    relative: bool = False
    overlapping: tuple[str, ...] = ()
    policy: str = "interpolate"
    _cache: dict[str, dict[str, float]] = field(default_factory=dict, repr=False)

    def __getitem__(self, criterion: str) -> Mapping[str, float]:
        if criterion not in self._cache:
            if criterion not in self.criteria:
                raise KeyError(criterion)
            index = self.criteria.index(criterion)
            row = self.sums[index].tolist()  # Python floats: the same arithmetic, much faster
            values: dict[str, float] = {"n": float(row[k.FIELD_N])}
            recipe = _row_recipe(
                self.measures,
                tuple(self.thresholds.tolist()),
                criterion.startswith(GT_FREE_PREFIX),
            )
            for name, derive in recipe:
                if derive is _FROM_QUANTILES:
                    values[name] = self.quantiles.get(criterion, {}).get(name, math.nan)
                elif callable(derive):
                    values[name] = float(derive(row))
                else:
                    values[name] = derive
            values.setdefault("density", float(_FROM_SUMS["density"](row)))
            self._cache[criterion] = values
        return self._cache[criterion]

    def to_dict(self) -> dict[str, dict[str, float]]:
        """Plain nested dict (criterion → measure → value), JSON-ready apart from nan.

        Counts (``n``, ``bmp_count``) are integers, as they are in the sums.
        """
        return {
            criterion: {
                name: int(value) if name in COUNT_MEASURES and math.isfinite(value) else value
                for name, value in self[criterion].items()
            }
            for criterion in self.criteria
        }

    def without_camera(self) -> Scores:
        """These scores with the depth measures (SZE, ``*_z``, irmse) unknown: nan.

        For a frame scored without a camera: its pixel measures need none, but its SZE would be
        relative (``f·B := 1``) and could not be added to metric frames.
        """
        sums = self.sums.copy()
        sums[:, list(DEPTH_FIELDS)] = math.nan
        return dataclasses.replace(self, sums=sums, relative=False, _cache={})

    @classmethod
    def combine(cls, parts: Sequence[Scores]) -> Scores:
        """Scores of several frames together: sums of sums (quantiles are not summable: nan)."""
        first = first_of_combinable(parts, "scores")
        for part in parts[1:]:
            if part.policy != first.policy:
                raise ConfigurationError(
                    f"cannot combine scores of the '{first.policy}' and '{part.policy}' missing policies"
                )
            if part.relative != first.relative:
                raise ConfigurationError(
                    "cannot combine metric SZE (with a camera) and relative SZE (without)"
                )
        total = np.sum([part.sums for part in parts], axis=0)
        return cls(
            criteria=first.criteria,
            measures=first.measures,
            sums=total,
            thresholds=first.thresholds,
            relative=first.relative,
            overlapping=first.overlapping,
            policy=first.policy,
        )
