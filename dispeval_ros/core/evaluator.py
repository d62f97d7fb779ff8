"""The scoring engine: GT-side preparation once per ground-truth map, one fused pass per method."""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from dispeval_ros.core import criteria as crit
from dispeval_ros.core import kernels
from dispeval_ros.core.camera import Camera
from dispeval_ros.core.measures import (
    DEPTH_MEASURES,
    FIELDS,
    Scores,
    parse_measures,
    quantile_level,
    thresholds_for,
)
from dispeval_ros.errors import (
    ConfigurationError,
    EmptyGroundTruthError,
    InputError,
    ShapeMismatchError,
)

POLICIES = {
    "interpolate": kernels.POLICY_INTERPOLATE,
    "thesis": kernels.POLICY_THESIS,
    "ignore": kernels.POLICY_IGNORE,
}
DEFAULT_CRITERIA = ("all", "visibility", "depth")


def as_disparity(array: object, what: str) -> np.ndarray:
    """A 2-D float32 C-contiguous disparity map, or a one-line error saying what came instead."""
    if not isinstance(array, np.ndarray):
        try:
            array = np.asarray(array)
        except (TypeError, ValueError) as error:
            raise InputError(f"{what} is not an array: {error}") from None
    if array.ndim != 2:
        raise InputError(f"{what} must be a 2-D disparity map, got an array of shape {array.shape}")
    if array.dtype.kind not in "fiu" or array.dtype.itemsize > 8:
        raise InputError(f"{what} must be a real-valued disparity map, got dtype {array.dtype}")
    return np.ascontiguousarray(array, dtype=np.float32)


@dataclass(frozen=True)
class _CacheInputs:
    """Everything a reference is built from, compared by content."""

    gt: np.ndarray
    camera: Camera | None
    masks: tuple[tuple[str, np.ndarray], ...]
    gt_right: np.ndarray | None
    roi: np.ndarray | None

    @classmethod
    def of(
        cls,
        gt: np.ndarray,
        camera: Camera | None,
        masks: Mapping[str, np.ndarray] | None,
        gt_right: np.ndarray | None,
        roi: np.ndarray | None,
    ) -> _CacheInputs:
        named = tuple(sorted((name, np.asarray(mask)) for name, mask in (masks or {}).items()))
        return cls(gt, camera, named, gt_right, roi)

    def copy(self) -> _CacheInputs:
        """Private copies, so later in-place changes of the caller's arrays are noticed."""
        return _CacheInputs(
            self.gt.copy(),
            self.camera,
            tuple((name, mask.copy()) for name, mask in self.masks),
            None if self.gt_right is None else np.array(self.gt_right, copy=True),
            None if self.roi is None else np.array(self.roi, copy=True),
        )

    def matches(self, other: _CacheInputs) -> bool:
        """Same camera and same array contents (shapes included)."""
        return (
            self.camera == other.camera
            and _same(self.gt, other.gt)
            and len(self.masks) == len(other.masks)
            and all(
                a == c and _same(b, d)
                for (a, b), (c, d) in zip(self.masks, other.masks, strict=True)
            )
            and _same(self.gt_right, other.gt_right)
            and _same(self.roi, other.roi)
        )


def _same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    """Same shape, dtype and bit pattern (NaN payloads and signed zeros included).

    Comparing raw bytes is ten times cheaper than a value comparison with ``equal_nan``; the
    rare arrays equal in value but not in bits (``-0.0``, other NaN payloads) merely build
    their reference again.
    """
    if a is b:
        return True
    if a is None or b is None:
        return False
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    words_a, words_b = _raw_words(a), _raw_words(b)
    step = words_a.size // 1024
    if step > 1 and not np.array_equal(words_a[::step], words_b[::step]):
        return False  # another map: a thousand spread-out words almost always tell at once
    return bool(np.array_equal(words_a, words_b))


def _raw_words(array: np.ndarray) -> np.ndarray:
    """The array's bytes as one flat vector of 64-bit words (of bytes if the size is not a multiple of 8)."""
    raw = np.ascontiguousarray(array).reshape(-1).view(np.uint8)
    if raw.size % 8 == 0:
        return raw.view(np.uint64)
    return raw


@dataclass(frozen=True)
class Reference:
    """A ground-truth map made ready for scoring: its partition and GT-side terms.

    Build it with :meth:`Evaluator.reference` and pass it to :meth:`Evaluator.score` in
    place of the GT to score many methods against the same map without redoing any GT work.
    """

    gt: np.ndarray
    partition: crit.Partition
    camera: Camera | None
    gt_sorted: np.ndarray
    fb: float
    depth_offset: float

    @property
    def shape(self) -> tuple[int, int]:
        """Image size (rows, columns)."""
        return self.partition.shape


class Evaluator:
    """Scores estimated disparity maps against ground truth by criterion (METHOD.md §1–3).

    >>> ev = Evaluator(criteria=("all", "visibility", "depth"))
    >>> scores = ev.score(gt, est, camera=Camera(f=721.5, baseline=0.54))  # doctest: +SKIP
    >>> scores["interior"]["sze"], scores["interior"]["n"]  # doctest: +SKIP
    """

    def __init__(
        self,
        criteria: Sequence[str] = DEFAULT_CRITERIA,
        measures: Sequence[str] | None = None,
        missing: str = "interpolate",
        delta: float = 1.0,
        mu: float = 0.01,
        *,
        boundary_gap: float = 2.0,
        boundary_width: int = 9,
        boundary_mode: str = "auto",
        occlusion_tolerance: float = 1.0,
        depth_ranges: Sequence[tuple[float, float]] | None = None,
        roi_names: Mapping[int, str] | None = None,
        cache_size: int = 4,
    ) -> None:
        if isinstance(criteria, str):
            criteria = (criteria,)
        unknown = [c for c in criteria if c not in crit.CRITERION_SETS]
        if unknown or not criteria:
            raise ConfigurationError(
                f"unknown criterion set '{', '.join(unknown) or '(none)'}'; "
                f"choose from {', '.join(crit.CRITERION_SETS)}"
            )
        if missing not in POLICIES:
            raise ConfigurationError(
                f"unknown missing-estimate policy '{missing}'; choose from {', '.join(POLICIES)}"
            )
        for name, value in (("delta", delta), ("mu", mu)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ConfigurationError(f"{name} must be a positive number, got {value!r}")
        self.criteria = tuple(dict.fromkeys(criteria))
        self.measures = parse_measures(measures)
        self.missing = missing
        self.delta = float(delta)
        self.mu = float(mu)
        self.boundary_gap = float(boundary_gap)
        self.boundary_width = int(boundary_width)
        if boundary_mode not in crit.BOUNDARY_MODES:
            raise ConfigurationError(
                f"unknown boundary mode '{boundary_mode}'; choose from "
                f"{', '.join(crit.BOUNDARY_MODES)}"
            )
        self.boundary_mode = boundary_mode
        self.occlusion_tolerance = float(occlusion_tolerance)
        self.depth_ranges = list(depth_ranges) if depth_ranges else None
        self.roi_names = dict(roi_names) if roi_names else None
        self.thresholds = thresholds_for(self.measures, self.delta)
        self._quantiles = [m for m in self.measures if quantile_level(m) is not None]
        self._depth_terms = any(m in DEPTH_MEASURES for m in self.measures)
        self._cache: list[tuple[_CacheInputs, Reference]] = []
        self._cache_size = cache_size
        self._local = threading.local()

    # -- ground-truth side ------------------------------------------------------------------

    def reference(
        self,
        gt: np.ndarray,
        camera: Camera | None = None,
        *,
        masks: Mapping[str, np.ndarray] | None = None,
        gt_right: np.ndarray | None = None,
        roi: np.ndarray | None = None,
    ) -> Reference:
        """Partition a GT map and compute its GT-side terms (once per GT map)."""
        gt = as_disparity(gt, "the ground truth")
        masks = dict(masks or {})
        unknown = set(masks) - {"all", "nonocc", "disc"}
        if unknown:
            raise ConfigurationError(
                f"unknown mask name(s) {', '.join(sorted(unknown))}; known: all, nonocc, disc"
            )
        bool_masks = {name: self._mask(name, mask, gt) for name, mask in masks.items()}
        right = None if gt_right is None else as_disparity(gt_right, "the right-view ground truth")
        valid = crit.valid_ground_truth(gt, bool_masks.get("all"))
        if not valid.any():
            raise EmptyGroundTruthError(
                "the ground truth has no valid point (every value is NaN, inf or ≤ 0"
                + (" inside the 'all' mask)" if "all" in bool_masks else ")")
            )
        if set(self.criteria) <= set(crit.STANDARD_SETS):
            partition, gt_sorted = crit.standard_partition(
                gt,
                valid,
                self.criteria,
                self._visibility_options(bool_masks, right),
                camera=camera,
                depth_ranges=self.depth_ranges,
            )
        else:
            built: dict[str, crit.CriterionSet] = {}
            for name in self.criteria:
                built[name] = self._criterion_set(
                    name, gt, valid, camera, bool_masks, right, roi, built
                )
            partition = crit.build_partition(valid, [built[name] for name in self.criteria])
            gt_sorted = np.empty(partition.order.shape, dtype=np.float32)  # a plain gather
            kernels.gather_estimate(
                gt.ravel(), partition.order, kernels.POSITIVE, math.inf, 0.0, 0.0, False, gt_sorted
            )
        fb = camera.fb if camera else 1.0
        doffs = camera.doffs if camera else 0.0
        depth_offset = doffs + self.mu
        return Reference(
            gt=gt,
            partition=partition,
            camera=camera,
            gt_sorted=gt_sorted,
            fb=fb,
            depth_offset=depth_offset,
        )

    @staticmethod
    def _mask(name: str, mask: np.ndarray, gt: np.ndarray) -> np.ndarray:
        mask = np.asarray(mask)
        if mask.shape != gt.shape:
            raise ShapeMismatchError(
                f"the '{name}' mask is {crit.size_text(mask.shape)} but the ground truth is "
                f"{crit.size_text(gt.shape)}"
            )
        return crit.inside_mask(f"the '{name}' mask", mask)

    def _criterion_set(
        self,
        name: str,
        gt: np.ndarray,
        valid: np.ndarray,
        camera: Camera | None,
        masks: Mapping[str, np.ndarray],
        gt_right: np.ndarray | None,
        roi: np.ndarray | None,
        built: dict[str, crit.CriterionSet],
    ) -> crit.CriterionSet:
        """One criterion set; ``built`` holds the sets made so far (legacy reuses visibility)."""
        if name == "all":
            return crit.all_set(valid)
        if name in ("visibility", "legacy"):
            visibility = built.get("visibility") or crit.visibility_set(
                gt, valid, **vars(self._visibility_options(masks, gt_right))
            )
            return visibility if name == "visibility" else crit.legacy_set(visibility)
        if name == "depth":
            return crit.depth_set(gt, valid, camera=camera, ranges=self.depth_ranges)
        if roi is None:
            raise ConfigurationError(
                "the 'roi' criterion set needs a region-of-interest mask or label image"
            )
        return crit.roi_set(valid, np.asarray(roi), self.roi_names)

    def _visibility_options(
        self, masks: Mapping[str, np.ndarray], gt_right: np.ndarray | None
    ) -> crit.VisibilityOptions:
        """How this evaluator finds the visibility classes, given the official masks."""
        return crit.VisibilityOptions(
            nonocc=masks.get("nonocc"),
            disc=masks.get("disc"),
            gt_right=gt_right,
            gap=self.boundary_gap,
            width=self.boundary_width,
            tolerance=self.occlusion_tolerance,
            boundary_mode=self.boundary_mode,
        )

    def _cached_reference(
        self,
        gt: np.ndarray,
        camera: Camera | None,
        masks: Mapping[str, np.ndarray] | None,
        gt_right: np.ndarray | None,
        roi: np.ndarray | None,
    ) -> Reference:
        """The reference of ``gt``, reused while the same GT and extras come again unchanged.

        Entries hold private copies of every input and are compared by bit pattern, newest
        first, so changing an array in place, or passing new masks in a reused dict, builds a
        new reference.
        """
        inputs = _CacheInputs.of(gt, camera, masks, gt_right, roi)
        for index in range(len(self._cache) - 1, -1, -1):
            cached, reference = self._cache[index]
            if cached.matches(inputs):
                if index != len(self._cache) - 1:
                    self._cache.append(self._cache.pop(index))
                return reference
        reference = self.reference(gt, camera, masks=masks, gt_right=gt_right, roi=roi)
        self._cache.append((inputs.copy(), reference))
        while len(self._cache) > self._cache_size:
            self._cache.pop(0)
        return reference

    # -- method side ----------------------------------------------------------------------

    def score(
        self,
        gt: np.ndarray | Reference,
        est: np.ndarray,
        camera: Camera | None = None,
        *,
        masks: Mapping[str, np.ndarray] | None = None,
        gt_right: np.ndarray | None = None,
        roi: np.ndarray | None = None,
        est_range: tuple[float, float] | None = None,
        est_offset: float = 0.0,
    ) -> Scores:
        """Score one estimated map: criterion → measure → value (``"n"``: point count).

        ``gt`` is a GT map (its partition is cached while it stays the same) or a
        :class:`Reference`. Valid estimates are finite and > 0 (files), or with ``est_range``
        (a DisparityImage's ``[min_disparity, max_disparity]``) inside it, 0 and negative
        values included. ``est_offset``: the estimate's values are ``E + est_offset`` (a
        DisparityImage's values are offset-corrected by ``doffs``); validity is tested on the
        values as given, the measures score ``E``.
        """
        if isinstance(gt, Reference):
            reference = gt
        else:
            reference = self._cached_reference(
                as_disparity(gt, "the ground truth"), camera, masks, gt_right, roi
            )
        estimate = as_disparity(est, "the estimate")
        if estimate.shape != reference.shape:
            raise ShapeMismatchError(
                f"the estimate is {crit.size_text(estimate.shape)} but the ground truth is "
                f"{crit.size_text(reference.shape)}"
            )
        partition = reference.partition
        values = self._buffer("values", partition.order.shape, np.float32)
        shift = self.gather(reference, estimate, values, est_range, est_offset)
        cell_sums = np.zeros((partition.offsets.shape[0] - 1, FIELDS), dtype=np.float64)
        kernels.accumulate_cells(
            values,
            partition.offsets,
            reference.gt_sorted,
            reference.fb,
            reference.depth_offset,
            self.mu,
            self.thresholds,
            0.0 if self.missing == "ignore" else 1.0,
            self._depth_terms,
            shift,
            cell_sums,
        )
        sums = partition.membership.astype(np.float64) @ cell_sums
        quantiles = self._quantile_values(reference, values, shift) if self._quantiles else {}
        return Scores(
            criteria=partition.criteria,
            measures=self.measures,
            sums=sums,
            thresholds=self.thresholds,
            quantiles=quantiles,
            relative=reference.camera is None,
            overlapping=partition.overlapping,
            policy=self.missing,
        )

    def gather(
        self,
        reference: Reference,
        estimate: np.ndarray,
        out: np.ndarray,
        est_range: tuple[float, float] | None = None,
        est_offset: float = 0.0,
    ) -> float:
        """Write the estimate at the reference's evaluated pixels (partition order) to ``out``.

        Validity is in the sign and the missing policy applied, as :meth:`score` scores it
        (pair measures gather both frames' estimates the same way); the value scored is
        ``|out| + shift``, the returned ``shift`` (:func:`estimate_coding`). ``estimate`` is
        a float32 map of the reference's shape (:func:`as_disparity`).
        """
        lo, hi, base, shift = estimate_coding(est_range, est_offset)
        coded = self.missing == "interpolate"
        source = self.normalise(estimate, est_range, est_offset) if coded else estimate
        order = reference.partition.order
        kernels.gather_estimate(source.ravel(), order, lo, hi, base, shift, coded, out)
        return shift

    def normalise(
        self,
        estimate: np.ndarray,
        est_range: tuple[float, float] | None = None,
        est_offset: float = 0.0,
    ) -> np.ndarray:
        """The estimate with validity in the sign bit and the missing policy applied.

        Positive: a valid estimate; otherwise missing, scored as the negated value (KITTI
        background interpolation under ``interpolate``, 0 otherwise); the value is
        ``|coded| + shift`` of :func:`estimate_coding`. The returned buffer is reused by the
        next call in the same thread.
        """
        estimate = as_disparity(estimate, "the estimate")
        lo, hi, base, shift = estimate_coding(est_range, est_offset)
        buffer = self._buffer("work", estimate.shape, np.float32)
        kernels.normalise_estimate(estimate, lo, hi, base, shift, POLICIES[self.missing], buffer)
        return buffer

    def error_map(
        self,
        reference: Reference,
        est: np.ndarray,
        est_range: tuple[float, float] | None = None,
        est_offset: float = 0.0,
    ) -> np.ndarray:
        """Absolute error per pixel as scored (after the missing policy); NaN where not evaluated.

        For display (error images), not for scoring: it allocates a full-size image.
        """
        work = self.normalise(as_disparity(est, "the estimate"), est_range, est_offset)
        shift = estimate_coding(est_range, est_offset)[3]
        error = np.abs(np.abs(work) + np.float32(shift) - reference.gt)
        error[reference.partition.cells < 0] = np.nan
        if self.missing == "ignore":
            error[work <= 0] = np.nan
        return error

    def _buffer(self, name: str, shape: tuple[int, ...], dtype: type) -> np.ndarray:
        """A per-thread scratch array, reallocated only when the shape changes."""
        buffer = getattr(self._local, name, None)
        if buffer is None or buffer.shape != shape:
            buffer = np.empty(shape, dtype=dtype)
            setattr(self._local, name, buffer)
        return buffer

    def _quantile_values(
        self, reference: Reference, values: np.ndarray, shift: float = 0.0
    ) -> dict[str, dict[str, float]]:
        """ETH3D-style error quantiles: the value at index ⌊N·q/100⌋ of the sorted errors.

        Each cell's errors are sorted once; a criterion's order statistics are then read off
        the union of its cells' sorted errors (:func:`kth_smallest`), without sorting it.
        """
        partition = reference.partition
        raw = values.astype(np.float64)
        errors = np.abs(np.abs(raw) + shift - reference.gt_sorted)
        offsets = partition.offsets
        cells = []
        for cell in range(offsets.shape[0] - 1):
            part = errors[offsets[cell] : offsets[cell + 1]]
            if self.missing == "ignore":  # only evaluated points
                part = part[raw[offsets[cell] : offsets[cell + 1]] > 0]
            part.sort()  # in place: ``errors`` is this call's own
            cells.append(part)
        levels = {name: quantile_level(name) or 0.0 for name in self._quantiles}
        result: dict[str, dict[str, float]] = {}
        for index, criterion in enumerate(partition.criteria):
            parts = [cells[c] for c in np.flatnonzero(partition.membership[index])]
            size = sum(part.size for part in parts)
            if not size:
                result[criterion] = dict.fromkeys(self._quantiles, math.nan)
                continue
            positions = {
                name: min(math.floor(size * level / 100.0), size - 1)
                for name, level in levels.items()
            }
            found = kth_smallest(parts, sorted(set(positions.values())))
            result[criterion] = {name: found[p] for name, p in positions.items()}
        return result


#: Candidate values per sorted part in :func:`kth_smallest`'s first step.
KTH_PROBES = 256


def estimate_coding(
    est_range: tuple[float, float] | None, offset: float = 0.0
) -> tuple[float, float, float, float]:
    """``(lo, hi, base, shift)`` the kernels code and score an estimate with.

    No range, or a lower end of −inf: valid means > 0 (files' rule); else valid means
    inside the range (a NaN bound: nothing). ``base``, ``shift``:
    :func:`~dispeval_ros.core.kernels.coding`.
    """
    lo, hi = est_range if est_range is not None else (-math.inf, math.inf)
    lo = kernels.POSITIVE if lo == -math.inf else float(lo)
    base, shift = kernels.coding(lo, float(offset))
    return lo, float(hi), base, shift


def kth_smallest(parts: Sequence[np.ndarray], ks: Sequence[int]) -> dict[int, float]:
    """The ``k``-th smallest value (0-based) of the union of sorted arrays, for each ``k``.

    Every ``step``-th value of each part (and its largest) is a probe; how many values are
    ≤ each probe follows from binary searches. The ``k``-th value lies above the last probe
    with fewer than ``k + 1`` values below or at it and at or below the next, so only the
    few values between those two probes are sorted. Exact, ties included.
    """
    parts = [part for part in parts if part.size]
    if len(parts) == 1:
        return {k: float(parts[0][k]) for k in ks}
    total = sum(part.size for part in parts)
    step = max(1, total // (KTH_PROBES * len(parts)))
    samples = [part[step - 1 :: step] for part in parts]
    largest = np.array([part[-1] for part in parts])
    probes = np.unique(np.concatenate([*samples, largest]))
    ranks = np.zeros(probes.shape[0], dtype=np.int64)  # values ≤ each probe
    for part in parts:
        ranks += np.searchsorted(part, probes, side="right")
    found: dict[int, float] = {}
    for k in ks:
        upper = int(np.searchsorted(ranks, k + 1))  # the first probe with ≥ k + 1 values ≤ it
        if upper:
            below = int(ranks[upper - 1])
            starts = [int(np.searchsorted(p, probes[upper - 1], side="right")) for p in parts]
        else:
            below, starts = 0, [0] * len(parts)
        stops = [int(np.searchsorted(p, probes[upper], side="right")) for p in parts]
        window = np.concatenate([p[a:b] for p, a, b in zip(parts, starts, stops, strict=True)])
        found[k] = float(np.sort(window)[k - below])
    return found
