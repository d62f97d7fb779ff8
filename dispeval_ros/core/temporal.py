"""Temporal measures with ground truth: TEPE of consecutive frames, summable per criterion.

A method that is wrong by the same amount at t and t+1 is temporally consistent; TEPE scores
the change of the error, ``e = |(E_t − E_t+1) − (D_t − D_t+1)|``, at the same pixel (no
warping, as DynamicStereo defines it), over the pixels with ground truth in both frames,
classified by frame t's criteria. Like the frame measures, a pair yields per-criterion sums;
a sequence's score is the sum of its pairs' sums, so pooled scores stay exact. The measures
are declared in :data:`dispeval_ros.core.registry.PAIR_MEASURES`; the normalisation is a
:class:`Preset` (docs/method.md, "Temporal measures").
"""

from __future__ import annotations

import dataclasses
import functools
import math
import threading
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from dispeval_ros.core import criteria as crit
from dispeval_ros.core import kernels, registry
from dispeval_ros.core.evaluator import (
    POLICIES,
    Evaluator,
    Reference,
    as_disparity,
    estimate_coding,
)
from dispeval_ros.core.kernels.temporal import (
    PAIR_BAD,
    PAIR_COUNT,
    PAIR_EVAL,
    PAIR_N,
    PAIR_NONZERO,
    accumulate_pairs,
    gather_next_ground_truth,
)
from dispeval_ros.core.measures import (
    DEFAULT_BAD_THRESHOLDS,
    ByCriterion,
    bad_threshold,
    first_of_combinable,
    from_registry,
    thresholds_for,
)
from dispeval_ros.errors import ConfigurationError, ShapeMismatchError

_PREFIX = "tepe_"


def pair_bad_threshold(name: str) -> float | None:
    """The threshold of a ``tepe_bad_X`` measure name, else None."""
    return bad_threshold(name[len(_PREFIX) :]) if name.startswith(_PREFIX) else None


def pair_unit(name: str) -> str:
    """The unit of pair measure ``name`` from the registry (``tepe_bad_X`` for any X)."""
    key = "tepe_bad_X" if pair_bad_threshold(name) is not None else name
    return registry.PAIR_BY_NAME[key].unit


def _expanded(name: str) -> tuple[str, ...]:
    if name == "tepe_bad_X":
        return tuple(f"tepe_bad_{t:g}" for t in DEFAULT_BAD_THRESHOLDS)
    return (name,)


DEFAULT_PAIR_MEASURES = tuple(
    n for m in registry.PAIR_MEASURES if m.default for n in _expanded(m.name)
)
"""The pair measures scored unless others are asked for (bad counts at the frame defaults)."""


@dataclass(frozen=True)
class Preset:
    """How the pair measures are normalised (what every mean divides by)."""

    name: str
    denominator: str
    """The pair accumulator field the means divide by."""
    measures: tuple[str, ...]
    """The measures this preset scores by default."""
    exact_is_zero: bool
    """A mean over pixels whose errors are all exactly 0 is 0 (not nan): the clamped division
    of DynamicStereo's code (``sum / max(nonzero, 1e-5)``)."""
    description: str


PRESETS: dict[str, Preset] = {
    "dispeval": Preset(
        "dispeval", "n_pair_eval", DEFAULT_PAIR_MEASURES, False,
        "means over every scored pixel pair (GT in both frames), zero errors included",
    ),
    "dynamicstereo": Preset(
        "dynamicstereo", "n_pair_nonzero",
        ("tepe", "tepe_bad_0.5", "tepe_bad_1", "tepe_bad_2", "tepe_bad_3"), True,
        "DynamicStereo's evaluation: means over the scored pixel pairs whose temporal error is "
        "not exactly 0, per clip; clips averaged weighted by their frames",
    ),
}  # fmt: skip
DEFAULT_PRESET = "dispeval"


def parse_pair_measures(names: Iterable[str]) -> tuple[str, ...]:
    """Validate pair measure names (``tepe_bad_X`` takes any threshold)."""
    chosen: list[str] = []
    for name in names:
        known = name in registry.PAIR_BY_NAME and name not in registry.PAIR_FAMILIES
        if not known and pair_bad_threshold(name) is None:
            raise ConfigurationError(
                f"unknown pair measure '{name}'; known: {', '.join(DEFAULT_PAIR_MEASURES)} "
                "(tepe_bad_X for any threshold X)"
            )
        if name not in chosen:
            chosen.append(name)
    if not chosen:
        raise ConfigurationError("no pair measure chosen")
    return tuple(chosen)


@functools.lru_cache(maxsize=128)
def _derivation(
    name: str, thresholds: tuple[float, ...], preset: Preset
) -> Callable[[Sequence[float]], float]:
    """How ``name`` is computed from a row of pair sums under ``preset``."""
    threshold = pair_bad_threshold(name)
    if threshold is not None:
        field_name = registry.PAIR_SUM_FIELDS[PAIR_BAD + thresholds.index(threshold, 1)]
        measure = dataclasses.replace(registry.PAIR_BY_NAME["tepe_bad_X"], num=field_name)
    else:
        measure = registry.PAIR_BY_NAME[name]
    derive = from_registry(
        dataclasses.replace(measure, den=preset.denominator), registry.pair_field_index
    )
    if not preset.exact_is_zero:
        return derive
    return lambda row: 0.0 if row[PAIR_NONZERO] == 0 and row[PAIR_EVAL] > 0 else derive(row)


@dataclass
class PairScores(ByCriterion):
    """Pair measures of one method on one frame pair (or summed over pairs), by criterion.

    ``scores[criterion][measure]``; ``scores[criterion]["n_pair"]`` counts the pixels with GT in
    both frames. ``sums`` (criteria × pair fields) is what sequences add up; ``pairs`` how many
    frame pairs they hold.
    """

    criteria: tuple[str, ...]
    measures: tuple[str, ...]
    sums: np.ndarray
    thresholds: np.ndarray
    policy: str
    preset: Preset
    pairs: int = 1
    _cache: dict[str, dict[str, float]] = field(default_factory=dict, repr=False)

    def __getitem__(self, criterion: str) -> Mapping[str, float]:
        if criterion not in self._cache:
            if criterion not in self.criteria:
                raise KeyError(criterion)
            row = self.sums[self.criteria.index(criterion)].tolist()
            values = {"n_pair": float(row[PAIR_N])}
            thresholds = tuple(self.thresholds.tolist())
            for name in self.measures:
                values[name] = float(_derivation(name, thresholds, self.preset)(row))
            self._cache[criterion] = values
        return self._cache[criterion]

    def to_dict(self) -> dict[str, dict[str, float]]:
        """Plain nested dict (criterion → measure → value); ``n_pair`` an integer."""
        return {
            c: {k: int(v) if k == "n_pair" else v for k, v in self[c].items()}
            for c in self.criteria
        }

    @classmethod
    def restored(
        cls,
        criteria: Sequence[str],
        sums: object,
        thresholds: object,
        policy: str,
        preset: str,
    ) -> PairScores:
        """One pair's scores from the parts it is stored as (a database row, a status's keys).

        Raises ValueError when the parts do not fit together (no criterion, an unknown preset,
        sums that are not criteria × pair fields): the caller names what was damaged.
        """
        names = tuple(criteria)
        values = np.array(sums, dtype=np.float64)
        if not names or preset not in PRESETS or values.size != len(names) * PAIR_COUNT:
            raise ValueError(f"{len(names)} criteria, {values.size} sums, preset {preset!r}")
        return cls(
            criteria=names,
            measures=PRESETS[preset].measures,
            sums=values.reshape(len(names), PAIR_COUNT),
            thresholds=np.array(thresholds, dtype=np.float64),
            policy=policy,
            preset=PRESETS[preset],
        )

    @classmethod
    def combine(cls, parts: Sequence[PairScores]) -> PairScores:
        """Scores of several frame pairs together: sums of sums."""
        first = first_of_combinable(parts, "pair scores")
        for part in parts[1:]:
            if (part.policy, part.preset) != (first.policy, first.preset):
                raise ConfigurationError(
                    "cannot combine pair scores of different missing policies or presets"
                )
        return cls(
            criteria=first.criteria,
            measures=first.measures,
            sums=np.sum([part.sums for part in parts], axis=0),
            thresholds=first.thresholds,
            policy=first.policy,
            preset=first.preset,
            pairs=sum(part.pairs for part in parts),
        )


def frame_weighted_mean(sequences: Sequence[PairScores]) -> dict[str, dict[str, float]]:
    """Per-clip values averaged over clips, each weighted by its frames (pairs + 1).

    DynamicStereo's aggregate over a data set: each clip of consecutive frames (its pairs
    combined) is one value, weighted by its length. Not summable; with the ``dispeval`` preset,
    pool the sequences with :meth:`PairScores.combine` instead.
    """
    if not sequences:
        raise ConfigurationError("no sequence to average")
    PairScores.combine(sequences)  # the same criteria, thresholds, policy and preset
    weights = [part.pairs + 1 for part in sequences]
    total = float(sum(weights))
    first = sequences[0]
    return {
        criterion: {
            name: math.fsum(
                w * part[criterion][name] for w, part in zip(weights, sequences, strict=True)
            )
            / total
            for name in first.measures
        }
        for criterion in first.criteria
    }


@dataclass(frozen=True)
class PairReference:
    """Frame t's reference and frame t+1's ground truth gathered in frame t's partition order."""

    reference: Reference
    gt_next_sorted: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        """Image size (rows, columns)."""
        return self.reference.shape


@dataclass(frozen=True)
class PreparedEstimate:
    """One frame's estimate with the missing policy applied once, for both pairs it is in.

    Frame t is the later frame of pair (t−1, t) and the earlier of (t, t+1); each pair gathers
    it in its own frame's partition order, but the costly part (KITTI interpolation under
    ``interpolate``) depends on the estimate alone. ``source``: the coded map (validity in the
    sign) under ``interpolate``, else the estimate itself (coded while gathered). Made by
    :meth:`TemporalScorer.prepare`; the estimate must not change while it is in use.
    """

    source: np.ndarray
    shape: tuple[int, int]
    coding: tuple[float, float, float, float]
    """``(lo, hi, base, shift)`` of :func:`~dispeval_ros.core.evaluator.estimate_coding`."""
    missing: str
    """The missing policy it was prepared under."""


class TemporalScorer:
    """Scores consecutive frames' estimates with the pair measures (docs/method.md).

    The missing-estimate policy, δ and criteria are those of ``evaluator``, applied to both
    frames exactly as it applies them to one. Over a sequence, :meth:`prepare` each frame's
    estimate once and pass the prepared frames to :meth:`score` (the same sums, half the
    interpolation).

    >>> scorer = TemporalScorer(Evaluator(criteria=("all", "depth")))
    >>> pair = scorer.pair(scorer.evaluator.reference(gt_t), gt_t1)  # doctest: +SKIP
    >>> scorer.score(pair, est_t, est_t1)["all"]["tepe"]  # doctest: +SKIP
    >>> scorer.score(pair, scorer.prepare(est_t), scorer.prepare(est_t1))  # doctest: +SKIP
    """

    def __init__(
        self,
        evaluator: Evaluator,
        measures: Sequence[str] | None = None,
        preset: str = DEFAULT_PRESET,
    ) -> None:
        if preset not in PRESETS:
            raise ConfigurationError(
                f"unknown temporal preset '{preset}'; choose from {', '.join(PRESETS)}"
            )
        self.evaluator = evaluator
        self.preset = PRESETS[preset]
        self.measures = parse_pair_measures(self.preset.measures if measures is None else measures)
        bad = [f"bad_{t:g}" for t in map(pair_bad_threshold, self.measures) if t is not None]
        self.thresholds = thresholds_for(bad, evaluator.delta)
        self._local = threading.local()

    def pair(self, reference: Reference, gt_next: np.ndarray | Reference) -> PairReference:
        """Frame t's reference with frame t+1's ground truth (a map, or its own reference).

        Frame t+1's GT is valid where finite and > 0, and where its reference evaluates a
        point when one is given (so its official ``all`` mask counts).
        """
        if isinstance(gt_next, Reference):
            gt = gt_next.gt
            cells = gt_next.partition.cells.reshape(-1)
        else:
            gt = as_disparity(gt_next, "the next frame's ground truth")
            cells = np.empty(0, dtype=np.int32)
        _same_size(gt.shape, reference, "the next frame's ground truth")
        order = reference.partition.order
        sorted_next = np.empty(order.shape, dtype=np.float32)
        gather_next_ground_truth(gt.reshape(-1), cells, order, sorted_next)
        return PairReference(reference, sorted_next)

    def prepare(
        self,
        est: np.ndarray,
        *,
        est_range: tuple[float, float] | None = None,
        est_offset: float = 0.0,
    ) -> PreparedEstimate:
        """One frame's estimate ready for :meth:`score` as frame t of one pair and t+1 of the next.

        Validity and coding as :meth:`Evaluator.score`; under ``interpolate`` the interpolated
        map is kept (its own array), so each frame is interpolated once, not once per pair.
        """
        return self._prepared(as_disparity(est, "the estimate"), est_range, est_offset, True)

    def score(
        self,
        pair: PairReference,
        est: np.ndarray | PreparedEstimate,
        est_next: np.ndarray | PreparedEstimate,
        *,
        est_range: tuple[float, float] | None = None,
        est_offset: float = 0.0,
        next_range: tuple[float, float] | None = None,
        next_offset: float | None = None,
    ) -> PairScores:
        """Score one method's estimates of frames t and t+1: criterion → pair measure → value.

        Either estimate a map or one made by :meth:`prepare` (the same sums). Validity and
        coding of a map as :meth:`Evaluator.score` (``next_range`` and ``next_offset`` default to
        frame t's); a prepared estimate carries its own.
        """
        reference = pair.reference
        if next_range is None:
            next_range = est_range
        if next_offset is None:
            next_offset = est_offset
        values, values_next = self._buffers(reference.partition.order.shape)
        shifts = []
        for given, out, coding, what in (
            (est, values, (est_range, est_offset), "the estimate"),
            (est_next, values_next, (next_range, next_offset), "the next frame's estimate"),
        ):
            if isinstance(given, PreparedEstimate):
                if given.missing != self.evaluator.missing:
                    raise ConfigurationError(
                        f"{what} was prepared under the '{given.missing}' missing policy, "
                        f"this scorer's is '{self.evaluator.missing}'"
                    )
                prepared = given
            else:  # gathered before the next is prepared: the evaluator's buffer can be shared
                array = as_disparity(given, what)
                prepared = self._prepared(array, coding[0], coding[1], False)
            _same_size(prepared.shape, reference, what)
            lo, hi, base, shift = prepared.coding
            coded = prepared.missing == "interpolate"
            order = reference.partition.order
            kernels.gather_estimate(prepared.source, order, lo, hi, base, shift, coded, out)
            shifts.append(shift)
        shift, shift_next = shifts
        partition = reference.partition
        cell_sums = np.zeros((partition.offsets.shape[0] - 1, PAIR_COUNT), dtype=np.float64)
        accumulate_pairs(
            values,
            values_next,
            reference.gt_sorted,
            pair.gt_next_sorted,
            partition.offsets,
            self.thresholds,
            0.0 if self.evaluator.missing == "ignore" else 1.0,
            shift,
            shift_next,
            registry.TEPE_R_EPSILON,
            cell_sums,
        )
        return PairScores(
            criteria=partition.criteria,
            measures=self.measures,
            sums=partition.membership.astype(np.float64) @ cell_sums,
            thresholds=self.thresholds,
            policy=self.evaluator.missing,
            preset=self.preset,
        )

    def _prepared(
        self,
        estimate: np.ndarray,
        est_range: tuple[float, float] | None,
        est_offset: float,
        own: bool,
    ) -> PreparedEstimate:
        """As :meth:`prepare`; ``own=False`` keeps the evaluator's reused buffer (no copy)."""
        coding = estimate_coding(est_range, est_offset)
        missing = self.evaluator.missing
        source = estimate
        if missing == "interpolate" and own:  # written once into its own map (not copied)
            source = np.empty(estimate.shape, dtype=np.float32)
            kernels.normalise_estimate(estimate, *coding, POLICIES[missing], source)
        elif missing == "interpolate":
            source = self.evaluator.normalise(estimate, est_range, est_offset)
        shape = (int(estimate.shape[0]), int(estimate.shape[1]))
        return PreparedEstimate(source.reshape(-1), shape, coding, missing)

    def _buffers(self, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Per-thread scratch arrays for both gathered estimates, reallocated on a new size.

        Fresh megabyte arrays cost page faults on every call (more than the kernel's pass).
        """
        buffers = getattr(self._local, "values", None)
        if buffers is None or buffers[0].shape != shape:
            buffers = (np.empty(shape, dtype=np.float32), np.empty(shape, dtype=np.float32))
            self._local.values = buffers
        return buffers


def _same_size(shape: tuple[int, ...], reference: Reference, what: str) -> None:
    if shape != reference.shape:
        raise ShapeMismatchError(
            f"{what} is {crit.size_text(shape)} but the ground truth is "
            f"{crit.size_text(reference.shape)}"
        )
