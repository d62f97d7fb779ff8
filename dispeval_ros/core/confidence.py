"""Confidence-aware evaluation: sparsification curves, their area (AUC) and AUSE, by criterion.

A stereo node's confidence ranks its pixels. Keeping the most confident share ``δ`` (the
density) of a criterion's points and scoring them gives the **sparsification curve**
``ε(δ)``; its **AUC** is ``∫₀¹ ε(δ) dδ`` (Hu & Mordohai; Poggi et al.). Ranking by the true
error instead gives the **oracle** curve, whose area is the optimal AUC — for a bad-pixel
share ``ε``, ``ε + (1 − ε)·ln(1 − ε)`` — and **AUSE** is the area between the two.

Confidences come in incompatible conventions; a :class:`ConfidencePreset` says which end is
better and the range, and the values are cut into at most :data:`MAX_LEVELS` levels (one per
value for 8-bit confidences, so their ties are exact). Pixels of one level are tied: the curve
through a level is the expectation over their orders, the cumulative error growing linearly
in the level, which gives the area in closed form (:func:`sparsification`). Everything is
summed per cell and level (and per error bin for the oracle): pooled over a sequence, the
curves are exactly those of all pixels at once. Pure: arrays in, sums out.
"""

from __future__ import annotations

import functools
import math
import threading
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from dispeval_ros.core import criteria as crit
from dispeval_ros.core import registry
from dispeval_ros.core.evaluator import Evaluator, Reference
from dispeval_ros.core.kernels import confidence as k
from dispeval_ros.core.measures import DEFAULT_BAD_THRESHOLDS, bad_threshold
from dispeval_ros.core.registry import MAX_THRESHOLDS
from dispeval_ros.errors import ConfigurationError, InputError, ShapeMismatchError

MAX_LEVELS = 256
"""Confidence levels a map is cut into at most (8-bit confidences: one level per value)."""


@dataclass(frozen=True)
class ConfidencePreset:
    """A confidence convention: which end is better, and the range (None: the image type's)."""

    name: str
    higher_is_better: bool
    low: float | None
    high: float | None
    description: str

    def text(self) -> str:
        """The preset as written on a command line (``higher:0:1`` for a given range)."""
        if PRESETS.get(self.name) == self:  # a named preset as it is (not higher:LOW:HIGH)
            return self.name
        return f"{'higher' if self.higher_is_better else 'lower'}:{self.low:g}:{self.high:g}"


PRESETS: dict[str, ConfidencePreset] = {
    preset.name: preset
    for preset in (
        ConfidencePreset("zed", False, 0.0, 100.0,
                         "ZED ~/confidence/confidence_map: 32FC1 cost 0–100, lower is better"),
        ConfidencePreset("realsense", True, 0.0, 15.0,
                         "RealSense L515 confidence: mono8 grade 0–15, 15 is best"),
        ConfidencePreset("vpi", True, 0.0, 65535.0,
                         "NVIDIA VPI stereo confidence: 0–65535, higher is better"),
        ConfidencePreset("wls", True, 0.0, 255.0,
                         "OpenCV WLS getConfidenceMap(): 0–255, higher is better"),
        ConfidencePreset("higher", True, None, None,
                         "higher is better, over the image type's range (higher:LOW:HIGH)"),
        ConfidencePreset("lower", False, None, None,
                         "lower is better, over the image type's range (lower:LOW:HIGH)"),
    )
}  # fmt: skip
"""The known confidence conventions, by name."""
DEFAULT_PRESET = "higher"


def parse_preset(text: str) -> ConfidencePreset:
    """A preset by name, or ``higher:LOW:HIGH`` / ``lower:LOW:HIGH`` (one line if unknown)."""
    name, *bounds = text.strip().split(":")
    if name not in PRESETS or (bounds and name not in ("higher", "lower")):
        raise ConfigurationError(
            f"unknown confidence preset '{text}'; choose from {', '.join(PRESETS)} "
            "(higher:LOW:HIGH or lower:LOW:HIGH for a range of your own)"
        )
    preset = PRESETS[name]
    if not bounds:
        return preset
    try:
        low, high = (float(b) for b in bounds)
    except ValueError:
        raise ConfigurationError(
            f"confidence preset '{text}': expected {name}:LOW:HIGH with two numbers"
        ) from None
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise ConfigurationError(f"confidence preset '{text}': LOW must be below HIGH")
    return ConfidencePreset(name, preset.higher_is_better, low, high, preset.description)


@dataclass(frozen=True)
class Grading:
    """How one image type's values become levels (0: the most confident) under a preset."""

    levels: int
    low: float
    high: float
    higher_is_better: bool
    lut: np.ndarray
    """``level | CLAMPED`` (outside the range) per 8-bit value; empty for other types."""

    def level(self, values: np.ndarray) -> np.ndarray:
        """Levels of confidence values (NaN: ``levels``), as the kernel computes them."""
        value = np.asarray(values, dtype=np.float64)
        place = np.clip(value, self.low, self.high)
        place = (self.high - place) if self.higher_is_better else (place - self.low)
        with np.errstate(invalid="ignore"):
            level = np.minimum(np.floor(place * (self.levels / (self.high - self.low))),
                               self.levels - 1)  # fmt: skip
        return np.where(np.isnan(value), self.levels, level).astype(np.int64)


@functools.lru_cache(maxsize=64)
def grading(preset: ConfidencePreset, dtype: np.dtype) -> Grading:
    """The levels of ``dtype`` confidences under ``preset`` (one line if they cannot be read)."""
    dtype = np.dtype(dtype)
    if dtype.kind not in "uif" or dtype.itemsize > 8:
        raise InputError(f"a confidence must be a numeric image, got dtype {dtype}")
    low, high = preset.low, preset.high
    if low is None or high is None:
        if dtype.kind == "f":
            raise ConfigurationError(
                f"a {dtype} confidence has no range of its type: give the preset as "
                f"{preset.name}:LOW:HIGH"
            )
        info = np.iinfo(dtype)
        low, high = float(info.min), float(info.max)
    integral = dtype.kind in "ui" and low == math.floor(low) and high == math.floor(high)
    levels = min(MAX_LEVELS, int(high - low) + 1) if integral else MAX_LEVELS
    shape = Grading(levels, low, high, preset.higher_is_better, np.empty(0, dtype=np.int32))
    if dtype != np.uint8:
        return shape
    values = np.arange(256, dtype=np.float64)
    outside = ((values < low) | (values > high)).astype(np.int32)
    lut = (shape.level(values).astype(np.int32) | (outside * k.CLAMPED)).astype(np.int32)
    return Grading(levels, low, high, preset.higher_is_better, lut)


# The measures a sparsification curve can be drawn for (units and labels from the registry).
CURVE_MEASURES = ("bad_X", "d1", "mae", "mae_z")
DEFAULT_CURVE_MEASURES = (*(f"bad_{t:g}" for t in DEFAULT_BAD_THRESHOLDS), "d1", "mae", "mae_z")


def _frame_measure(measure: str) -> registry.Measure:
    """The frame measure a curve measure is drawn in: its unit and scale."""
    return registry.BY_NAME["bad_X" if bad_threshold(measure) is not None else measure]


def curve_unit(measure: str) -> str:
    """The unit of a curve measure, as the frame measure of the same name has it."""
    return _frame_measure(measure).unit


def parse_curve_measures(names: Iterable[str]) -> tuple[str, ...]:
    """Validate curve measure names (``bad_X`` takes any threshold)."""
    chosen: list[str] = []
    for name in names:
        if name not in CURVE_MEASURES[1:] and bad_threshold(name) is None:
            raise ConfigurationError(
                f"unknown confidence measure '{name}'; known: {', '.join(CURVE_MEASURES)} "
                "(bad_X for any threshold X)"
            )
        if name not in chosen:
            chosen.append(name)
    if not chosen:
        raise ConfigurationError("no confidence measure chosen")
    return tuple(chosen)


def sparsification(counts: np.ndarray, sums: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The curve through ranked groups of tied points, and its area ``∫₀¹ ε(δ) dδ``.

    ``counts[g]`` points with ``sums[g]`` total error in group ``g``, the best ranked first.
    Returns each non-empty group's end (density, mean error so far) and the area. Inside a
    group the cumulative error grows linearly in the density (the mean over the group's
    orders), so ``ε(δ) = a/δ + ē`` there and the area is exact:
    ``(S₀ − N₀·ē)/N · ln(N₁/N₀) + s/N`` for a group taking the points from ``N₀`` to ``N₁``.
    """
    counts = np.asarray(counts, dtype=np.float64)
    sums = np.asarray(sums, dtype=np.float64)
    kept = counts > 0
    counts, sums = counts[kept], sums[kept]
    total = counts.sum()
    if not total > 0:
        return np.empty(0), np.empty(0), math.nan
    ends = np.cumsum(counts)
    cumulative = np.cumsum(sums)
    starts = ends - counts
    before = cumulative - sums
    mean = sums / counts
    with np.errstate(divide="ignore", invalid="ignore"):
        growth = np.where(starts > 0, np.log(ends / np.where(starts > 0, starts, 1.0)), 0.0)
    area = float(np.sum((before - starts * mean) * growth + sums) / total)
    return ends / total, cumulative / ends, area


def optimal_auc(share: float) -> float:
    """The oracle's area for a bad share ``ε`` in [0, 1]: ``ε + (1 − ε)·ln(1 − ε)``."""
    return share if share >= 1.0 else share + (1.0 - share) * math.log1p(-share)


@dataclass(frozen=True)
class Curve:
    """One criterion's sparsification curve of one measure, in the measure's unit."""

    density: np.ndarray
    error: np.ndarray
    auc: float
    auc_opt: float
    oracle_density: np.ndarray
    oracle_error: np.ndarray

    def at(self, densities: np.ndarray, oracle: bool = False) -> np.ndarray:
        """The curve's exact error at ``densities`` in (0, 1] (the oracle's with ``oracle``).

        Between two group ends the kept error grows linearly in the density (ties averaged),
        so ``ε(δ) = S(δ)/δ`` is curved there, not straight: this is the curve to draw.
        """
        ends = self.oracle_density if oracle else self.density
        means = self.oracle_error if oracle else self.error
        wanted = np.asarray(densities, dtype=np.float64)
        if not ends.size:
            return np.full(wanted.shape, math.nan)
        kept = np.concatenate(([0.0], ends * means))  # S at each end, per point of the total
        starts = np.concatenate(([0.0], ends))
        return np.interp(wanted, starts, kept) / np.where(wanted > 0, wanted, math.nan)

    @property
    def ause(self) -> float:
        """The area between the curve and the oracle's."""
        return self.auc - self.auc_opt

    @property
    def ratio(self) -> float:
        """AUC over the optimal AUC (1: a perfect confidence)."""
        return self.auc / self.auc_opt if self.auc_opt > 0 else math.nan


@dataclass(frozen=True)
class ConfidenceSums:
    """One method's confidence sums by criterion: add frames' sums, then read the curves."""

    criteria: tuple[str, ...]
    thresholds: tuple[float, ...]
    levels: int
    depth: bool
    sums: np.ndarray
    """``[criterion, level, column]``: points, Σ|e|, Σ|ΔZ|, D1 count, one count per threshold
    (:mod:`~dispeval_ros.core.kernels.confidence`); the last level: no estimate or confidence."""
    errors: np.ndarray
    """``[criterion, error bin, (points, Σ|e|)]`` for the oracle."""
    depth_errors: np.ndarray
    """As ``errors`` for the depth error."""
    counters: np.ndarray
    """``[criterion, (missing, unrated, clamped)]`` point counts."""
    points: np.ndarray
    """Points of each criterion (missing estimates included)."""

    def __add__(self, other: ConfidenceSums) -> ConfidenceSums:
        if (other.criteria, other.thresholds, other.levels) != (
            self.criteria, self.thresholds, self.levels,
        ):  # fmt: skip
            raise ConfigurationError(
                "cannot pool confidence sums of different criteria, thresholds or levels"
            )
        return ConfidenceSums(
            self.criteria, self.thresholds, self.levels, self.depth and other.depth,
            self.sums + other.sums, self.errors + other.errors,
            self.depth_errors + other.depth_errors, self.counters + other.counters,
            self.points + other.points,
        )  # fmt: skip

    @classmethod
    def pooled(cls, parts: Sequence[ConfidenceSums]) -> ConfidenceSums:
        """The sums of many frames (one line if there are none or they differ)."""
        if not parts:
            raise ConfigurationError("no confidence sums to pool")
        return functools.reduce(cls.__add__, parts)

    def measures(self) -> tuple[str, ...]:
        """The curve measures these sums hold."""
        bad = tuple(f"bad_{t:g}" for t in self.thresholds)
        return (*bad, "d1", "mae", *(("mae_z",) if self.depth else ()))

    def curve(self, criterion: str, measure: str) -> Curve:
        """The sparsification curve and oracle of ``measure`` on ``criterion``."""
        index = self._index(criterion)
        rows = self.sums[index]
        counts = rows[:, k.LEVEL_N]
        column = self._column(measure)
        if column not in (k.LEVEL_SUM_E, k.LEVEL_SUM_EZ):  # a bad share: D1 or bad_X
            bad = rows[:, column]
            density, error, auc = sparsification(counts, bad)
            total = counts.sum()
            share = float(bad.sum() / total) if total > 0 else math.nan
            auc_opt = optimal_auc(share) if total > 0 else math.nan
            oracle_d, oracle_e, _ = sparsification(
                np.array([total - bad.sum(), bad.sum()]), np.array([0.0, bad.sum()])
            )
        else:
            density, error, auc = sparsification(counts, rows[:, column])
            bins = (self.errors if column == k.LEVEL_SUM_E else self.depth_errors)[index]
            oracle_d, oracle_e, auc_opt = sparsification(bins[:, 0], bins[:, 1])
        scale = _frame_measure(measure).scale
        return Curve(
            density, error * scale, auc * scale, auc_opt * scale, oracle_d, oracle_e * scale
        )

    def operating_point(self, criterion: str, measure: str, level: int) -> tuple[float, float]:
        """(density, error) keeping the points of levels ``0…level`` (a threshold's cut)."""
        index = self._index(criterion)
        rows = self.sums[index, : level + 1]
        total = self.sums[index, :, k.LEVEL_N].sum()
        kept = rows[:, k.LEVEL_N].sum()
        curve_column = self._column(measure)
        scale = _frame_measure(measure).scale
        density = float(kept / total) if total > 0 else math.nan
        error = float(rows[:, curve_column].sum() / kept * scale) if kept > 0 else math.nan
        return density, error

    def summary(self, measures: Sequence[str] | None = None) -> dict[str, dict[str, object]]:
        """Per criterion and measure: AUC, optimal AUC, AUSE, ratio and the curve's points (JSON)."""
        chosen = self.measures() if measures is None else measures
        result: dict[str, dict[str, object]] = {}
        for index, criterion in enumerate(self.criteria):
            points = float(self.points[index])
            missing, unrated, clamped = (float(v) for v in self.counters[index])
            entry: dict[str, object] = {
                "n": points,
                "density": (points - missing) / points if points > 0 else math.nan,
                "n_unrated": unrated,
                "n_clamped": clamped,
            }
            for measure in chosen:
                curve = self.curve(criterion, measure)
                entry[measure] = {
                    "unit": curve_unit(measure),
                    "auc": curve.auc,
                    "auc_opt": curve.auc_opt,
                    "ause": curve.ause,
                    "ratio": curve.ratio,
                    "density": curve.density.tolist(),
                    "error": curve.error.tolist(),
                }
            result[criterion] = entry
        return result

    def _index(self, criterion: str) -> int:
        if criterion not in self.criteria:
            raise ConfigurationError(
                f"no criterion '{criterion}' in these confidence sums; "
                f"known: {', '.join(self.criteria)}"
            )
        return self.criteria.index(criterion)

    def _threshold(self, threshold: float | None) -> int:
        if threshold not in self.thresholds:
            known = ", ".join(f"bad_{t:g}" for t in self.thresholds)
            raise ConfigurationError(f"no confidence sums at bad_{threshold:g}; these hold {known}")
        return self.thresholds.index(threshold)

    def _column(self, measure: str) -> int:
        threshold = bad_threshold(measure)
        if threshold is not None:
            return k.LEVEL_BAD + self._threshold(threshold)
        columns = {"d1": k.LEVEL_D1, "mae": k.LEVEL_SUM_E, "mae_z": k.LEVEL_SUM_EZ}
        if measure not in columns:
            raise ConfigurationError(f"no confidence measure '{measure}' in these sums")
        if measure == "mae_z" and not self.depth:
            raise ConfigurationError("mae_z needs the camera (focal length and baseline)")
        return columns[measure]


class ConfidenceScorer:
    """Scores one method's estimate with its confidence map against a reference, by criterion.

    The missing-estimate policy, δ, μ and criteria are ``evaluator``'s: a missing estimate is
    ranked last (``ignore``: not scored), as are points whose confidence is NaN.

    >>> scorer = ConfidenceScorer(Evaluator(criteria=("all",)), parse_preset("wls"))
    >>> sums = scorer.score(scorer.evaluator.reference(gt), est, confidence)  # doctest: +SKIP
    >>> sums.curve("all", "bad_2").auc  # doctest: +SKIP
    """

    def __init__(
        self,
        evaluator: Evaluator,
        preset: ConfidencePreset,
        thresholds: Sequence[float] = DEFAULT_BAD_THRESHOLDS,
    ) -> None:
        self.evaluator = evaluator
        self.preset = preset
        self.thresholds = tuple(sorted({float(t) for t in thresholds}))
        if not self.thresholds or not all(t > 0 and math.isfinite(t) for t in self.thresholds):
            raise ConfigurationError("confidence thresholds must be positive numbers")
        if len(self.thresholds) > MAX_THRESHOLDS:
            raise ConfigurationError(
                f"at most {MAX_THRESHOLDS} confidence thresholds at once, got {len(self.thresholds)}"
            )
        padded = (*self.thresholds, *(math.inf,) * (MAX_THRESHOLDS - len(self.thresholds)))
        self._threshold_array = np.array(padded, dtype=np.float64)
        self._local = threading.local()

    def score(
        self,
        reference: Reference,
        est: np.ndarray,
        confidence: np.ndarray,
        *,
        est_range: tuple[float, float] | None = None,
        est_offset: float = 0.0,
    ) -> ConfidenceSums:
        """One frame's sums; validity and coding of the estimate as :meth:`Evaluator.score`."""
        estimate = self._same_size(est, reference, "the estimate")
        rating = self._same_size(confidence, reference, "the confidence")
        if rating.dtype.kind == "f" and not np.isfinite(rating).any():
            raise InputError("the confidence has no finite value (NaN or inf everywhere)")
        grade = grading(self.preset, rating.dtype)
        partition = reference.partition
        size = partition.order.shape[0]
        values = self._buffer("values", size, np.float32)
        level_of = self._buffer("levels", size, np.int32)
        shift = self.evaluator.gather(reference, estimate, values, est_range, est_offset)
        if grade.lut.size:
            k.gather_lut_levels(rating.reshape(-1), partition.order, grade.lut, level_of)
        else:
            k.gather_levels(
                rating.reshape(-1), partition.order, grade.low, grade.high,
                grade.higher_is_better, grade.levels, level_of,
            )  # fmt: skip
        cells = partition.offsets.shape[0] - 1
        grades = 2 * (len(self.thresholds) + 1)
        table = np.zeros((cells, grade.levels + 2, 2 + grades))
        errors = np.zeros((cells, k.ERROR_BINS + 1, 2))
        depth_errors = np.zeros((cells, k.ERROR_BINS + 1, 2))
        counters = np.zeros((cells, k.COUNTERS))
        depth = reference.camera is not None and math.isfinite(reference.fb)
        k.accumulate_levels(
            values, reference.gt_sorted, level_of, partition.offsets, grade.levels,
            self._threshold_array, 0.0 if self.evaluator.missing == "ignore" else 1.0, shift,
            reference.fb if depth else 0.0, reference.depth_offset, self.evaluator.mu, depth,
            table, errors, depth_errors, counters,
            self._buffer("scratch_float", (2, size), np.float64),
            self._buffer("scratch_int", (4, size), np.int32),
        )  # fmt: skip
        membership = partition.membership.astype(np.float64)
        level_sums = np.tensordot(membership, table[:, :-1], axes=(1, 0))
        counts = level_sums[..., 2:]
        beyond = np.cumsum(counts[..., ::-1].reshape(*counts.shape[:2], -1, 2).sum(-1), -1)
        columns = [
            counts.sum(-1),
            level_sums[..., 0],
            level_sums[..., 1],
            counts[..., 1::2].sum(-1),
            *(beyond[..., -2 - j] for j in range(len(self.thresholds))),
        ]
        return ConfidenceSums(
            criteria=partition.criteria,
            thresholds=self.thresholds,
            levels=grade.levels,
            depth=depth,
            sums=np.stack(columns, axis=-1),
            errors=np.tensordot(membership, errors[:, :-1], axes=(1, 0)),
            depth_errors=np.tensordot(membership, depth_errors[:, :-1], axes=(1, 0)),
            counters=np.tensordot(membership, counters, axes=(1, 0)),
            points=membership @ np.diff(partition.offsets).astype(np.float64),
        )

    @staticmethod
    def _same_size(array: object, reference: Reference, what: str) -> np.ndarray:
        image = np.asarray(array)
        if image.ndim != 2:
            raise InputError(f"{what} must be a 2-D image, got an array of shape {image.shape}")
        if image.shape != reference.shape:
            raise ShapeMismatchError(
                f"{what} is {crit.size_text(image.shape)} but the ground truth is "
                f"{crit.size_text(reference.shape)}"
            )
        if what == "the estimate":
            return np.ascontiguousarray(image, dtype=np.float32)
        return np.ascontiguousarray(image)

    def _buffer(self, name: str, shape: int | tuple[int, ...], dtype: type) -> np.ndarray:
        """A per-thread scratch array, reallocated only when the shape changes."""
        shape = (shape,) if isinstance(shape, int) else shape
        buffer = getattr(self._local, name, None)
        if buffer is None or buffer.shape != shape:
            buffer = np.empty(shape, dtype=dtype)
            setattr(self._local, name, buffer)
        return buffer


def level_of_threshold(grade: Grading, threshold: float) -> int:
    """The last level a confidence threshold keeps (values at least as confident as it)."""
    return int(grade.level(np.array([threshold]))[0])


def by_method(
    sums: Mapping[str, Sequence[ConfidenceSums]],
) -> dict[str, ConfidenceSums]:
    """Each method's frames pooled (methods with no frame left out)."""
    return {name: ConfidenceSums.pooled(parts) for name, parts in sums.items() if parts}
