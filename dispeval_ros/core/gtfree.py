"""Measures that need no ground truth: the left and right rectified images judge the estimate.

``vpe`` (view-prediction error, Szeliski's prediction error): the right image warped into the
left view by the estimate (``x − d``, linear interpolation along the row), mean absolute 8-bit
grey difference over the pixels whose target lies in the image and is not occluded according
to the estimate's own z-buffer. ``lrc``: the share of pixels whose right-view estimate (when a
method publishes one) disagrees by more than 1 px. Both follow the missing-estimate policy as
the GT measures do (the KITTI-interpolated estimate under ``interpolate``, ``E = 0`` under
``thesis``, holes left out under ``ignore``): scoring only the valid pixels would reward
methods that leave the hard pixels out.

Criteria without GT never depend on the method under test: ``all`` (every pixel), ``roi``
and ``texture`` (from the left image). They are named ``gtfree:<criterion>`` and their sums
are rows of an ordinary :class:`~dispeval_ros.core.measures.Scores`, so sequences stay exact
and stores, streams and models take them unchanged.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from dispeval_ros.core import criteria as crit
from dispeval_ros.core import kernels as k
from dispeval_ros.core import registry
from dispeval_ros.core.evaluator import POLICIES, _same, as_disparity, estimate_coding
from dispeval_ros.core.measures import (
    FIELDS,
    GT_FREE_MEASURES,
    GT_FREE_PREFIX,
    Scores,
    thresholds_for,
)
from dispeval_ros.errors import ConfigurationError, InputError, ShapeMismatchError

GT_FREE_CRITERION_SETS = ("all", "roi", "texture")
DEFAULT_GT_FREE_CRITERIA = ("all", "texture")
GT_FREE_SCORED = (*GT_FREE_MEASURES, *registry.names(needs=registry.NEEDS_NONE))
"""What a GT-free criterion reports (with ``n``, its number of pixels)."""
OCCLUSION_TOLERANCE = 1.0
"""A pixel is occluded when a pixel landing on the same right-view column has a disparity
larger by more than this (px): slanted surfaces land neighbours on one column too."""
LRC_THRESHOLD = 1.0
"""Left-right check: inconsistent when ``|d_L(x) − d_R(round(x − d_L))|`` exceeds this (px)."""


def is_gt_free(criterion: str) -> bool:
    """Whether a criterion was scored without ground truth."""
    return criterion.startswith(GT_FREE_PREFIX)


def grey8(image: object, what: str) -> np.ndarray:
    """A 2-D uint8 C-contiguous grey image, or a one-line error saying what came instead."""
    array = np.asarray(image)
    if array.ndim != 2 or array.dtype != np.uint8:
        raise InputError(
            f"{what} must be an 8-bit grey image, got {array.dtype} of shape {array.shape}"
        )
    return np.ascontiguousarray(array)


@njit(cache=True, nogil=True)
def cell_runs(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover
    """Runs of equal cells along each row: starts, cell of each run, first run of each row.

    A property of the partition (built once per frame), so scoring each method adds a run's
    terms in registers instead of finding where the cell changes pixel by pixel.
    """
    height, width = cells.shape
    count = 0
    for y in range(height):
        count += 1
        for x in range(1, width):
            count += 1 if cells[y, x] != cells[y, x - 1] else 0
    starts = np.empty(count + 1, dtype=np.int64)
    run_cells = np.empty(count, dtype=np.int32)
    row_first = np.empty(height + 1, dtype=np.int64)
    run = 0
    for y in range(height):
        row_first[y] = run
        for x in range(width):
            if x == 0 or cells[y, x] != cells[y, x - 1]:
                starts[run] = x
                run_cells[run] = cells[y, x]
                run += 1
    row_first[height] = run
    starts[count] = width
    return starts, run_cells, row_first


@njit(cache=True, nogil=True)
def neighbour_pairs(right: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """``right[y, x] + 256 · right[y, x + 1]`` (the last column repeated) as int32.

    Built once per frame: the interpolation then gathers both neighbours in one 32-bit load.
    """
    height, width = right.shape
    pairs = np.empty((height, width), dtype=np.int32)
    for y in range(height):
        for x in range(width - 1):
            pairs[y, x] = np.int32(right[y, x]) + 256 * np.int32(right[y, x + 1])
        pairs[y, width - 1] = np.int32(right[y, width - 1]) * 257
    return pairs


MASKED_CELLS = 4
"""Up to this many cells, a row adds its terms by one vectorised masked pass per cell
(``texture`` alternates every few pixels: per-run loops would be mostly overhead); more
cells, or the left-right check, go run by run."""
SPARE_SLOTS = 8
"""Z-buffer slots past the row that pixels landing nowhere write to, in turn: a run of holes
does not chain its stores through one address. One more slot after them holds +inf: pixels
that do not count in vpe read it, so they are hidden without a test of their own."""


@njit(cache=True, nogil=True, fastmath=k._FAST, error_model="numpy")
def photometric_sums(
    left: np.ndarray,
    right_pairs: np.ndarray,
    coded: np.ndarray,
    include_missing: bool,
    runs: tuple[np.ndarray, np.ndarray, np.ndarray],
    right_coded: np.ndarray,
    tolerance: float,
    lrc_threshold: float,
    cells: np.ndarray,
    sums: np.ndarray,
    shift: float = 0.0,
    right_shift: float = 0.0,
) -> None:  # pragma: no cover - compiled
    """Add one estimate's GT-free terms per cell (``cells`` < 0: not evaluated).

    ``coded`` is the estimate from :func:`~dispeval_ros.core.kernels.normalise_estimate`
    (validity in the sign, ``|coded| + shift`` the disparity ``x_l − x_r`` to warp with, see
    :func:`~dispeval_ros.core.kernels.coding`); ``include_missing`` is False under
    ``ignore``. ``right_pairs`` comes from :func:`neighbour_pairs`, ``runs`` from
    :func:`cell_runs`. ``right_coded`` is the right-view estimate coded the same way (its
    ``right_shift``), or 0×0 for none. ``tolerance`` ≥ 0.

    Per row (occlusion is along the row only): a vectorised pass of every pixel's geometry;
    one right-to-left pass that reads and writes the z-buffer at once (:func:`_row_visible`);
    a gather of both interpolation neighbours of each pixel in one 32-bit load; a vectorised
    pass of the absolute differences; the sums of the row's terms per cell (a masked pass per
    cell when there are few, else per run of one cell). The scalar passes are kept minimal:
    their loads and stores are the cost.
    """
    starts, run_cells, row_first = runs
    height, width = left.shape
    n_cells = sums.shape[0]
    floor = -np.inf if include_missing else 0.0  # coded values above it take part
    last = np.float64(width - 1)
    zbuffer = np.empty(width + SPARE_SLOTS + 1, dtype=np.float32)
    hidden = width + SPARE_SLOTS  # the +inf slot
    weight = np.empty(width, dtype=np.float64)
    column = np.empty(width, dtype=np.uint32)  # unsigned: no negative-index wrap-around
    target = np.empty(width, dtype=np.uint32)
    slot = np.empty(width, dtype=np.uint32)
    visible = np.empty(width, dtype=np.float64)
    difference = np.empty(width, dtype=np.float64)
    neighbours = np.empty(width, dtype=np.int32)
    check = right_coded.shape[0] == height
    for y in range(height):
        row = coded[y]
        for x in range(width):  # geometry: vectorises
            raw = row[x]
            d = np.float64(abs(raw)) + shift
            source = x - d
            clamped = min(max(source, 0.0), last)
            x0 = min(int(clamped), width - 2)  # x0 + 1 inside: at x − d = W − 1 the weight is 1
            landing = np.floor(source + 0.5)
            lands = (raw > floor) & (landing >= 0.0) & (landing < width)
            column[x] = x0
            weight[x] = clamped - x0
            counted = (raw > floor) & (source >= 0.0) & (source <= last)
            target[x] = int(clamped + 0.5) if counted else hidden  # clamped ≥ 0: floor
            slot[x] = int(landing) if lands else width + (x & (SPARE_SLOTS - 1))
        _row_visible(row, shift, target, slot, tolerance, zbuffer, visible)
        _gather(right_pairs[y], column, neighbours)
        left_row = left[y]
        for x in range(width):  # interpolation and difference: vectorises
            pair = neighbours[x]
            low = np.float64(pair & 255)
            predicted = low + weight[x] * (np.float64(pair >> 8) - low)
            difference[x] = abs(np.float64(left_row[x]) - predicted) * visible[x]  # × 1 or × 0
        if not check and n_cells <= MASKED_CELLS:
            for cell in range(n_cells):  # few cells: a masked pass each beats per-run loops
                _add_masked(sums[cell], cells[y], cell, row, visible, difference)
            continue
        for run in range(row_first[y], row_first[y + 1]):
            cell = run_cells[run]
            if cell < 0:
                continue
            start = starts[run]
            stop = starts[run + 1] if run + 1 < row_first[y + 1] else width
            n_valid = 0.0
            n_vpe = 0.0
            sum_vpe = 0.0
            for x in range(start, stop):
                n_valid += 1.0 if row[x] > 0.0 else 0.0
                n_vpe += visible[x]
                sum_vpe += difference[x]
            sums[cell, k.FIELD_N] += stop - start
            sums[cell, k.FIELD_VALID] += n_valid
            sums[cell, k.FIELD_N_VPE] += n_vpe
            sums[cell, k.FIELD_SUM_VPE] += sum_vpe
            if check:
                n_lrc, n_bad = _run_lrc(
                    row, right_coded[y], floor, start, stop, lrc_threshold, shift, right_shift
                )
                sums[cell, k.FIELD_N_LRC] += n_lrc
                sums[cell, k.FIELD_LRC] += n_bad


@njit(cache=True, nogil=True, fastmath=k._FAST, error_model="numpy")
def _add_masked(
    sums: np.ndarray,
    cells: np.ndarray,
    cell: int,
    coded: np.ndarray,
    visible: np.ndarray,
    difference: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Add one row's terms of the pixels of one cell (a branch-free pass that vectorises)."""
    n = 0.0
    n_valid = 0.0
    n_vpe = 0.0
    sum_vpe = 0.0
    for x in range(cells.shape[0]):
        inside = 1.0 if cells[x] == cell else 0.0
        n += inside
        n_valid += inside if coded[x] > 0.0 else 0.0
        n_vpe += inside * visible[x]
        sum_vpe += inside * difference[x]
    sums[k.FIELD_N] += n
    sums[k.FIELD_VALID] += n_valid
    sums[k.FIELD_N_VPE] += n_vpe
    sums[k.FIELD_SUM_VPE] += sum_vpe


@njit(cache=True, nogil=True, fastmath=k._FAST, error_model="numpy")
def _row_visible(
    coded: np.ndarray,
    shift: float,
    target: np.ndarray,
    slot: np.ndarray,
    tolerance: float,
    zbuffer: np.ndarray,
    visible: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """One row's z-buffer and visibility (1 or 0 per pixel), right to left, branch-free.

    A pixel can only be hidden by a pixel to its right (``tolerance`` ≥ 0), already in the
    z-buffer when it is read, so one pass both reads and writes it. Holes and occlusions are
    not predictable: no branches; indices are unsigned so that no negative-index wrap-around
    is computed. A small kernel of its own: inlined, its pointers spill.
    """
    width = coded.shape[0]
    zbuffer[:-1] = -np.inf
    zbuffer[-1] = np.inf  # what pixels that do not count read (``target``): never visible
    for i in range(width):
        x = np.uint64(width - 1 - i)
        d = np.float32(abs(coded[x]) + shift)
        seen = not np.float64(zbuffer[target[x]]) > np.float64(d) + tolerance
        here = slot[x]
        zbuffer[here] = max(zbuffer[here], d)
        visible[x] = 1.0 if seen else 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def _gather(values: np.ndarray, index: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """``out[x] = values[index[x]]``: gathers do not vectorise, the arithmetic after them does."""
    for x in range(index.shape[0]):
        out[x] = values[index[x]]


@njit(cache=True, nogil=True, fastmath=k._FAST, error_model="numpy")
def _run_lrc(
    coded: np.ndarray,
    right_coded: np.ndarray,
    floor: float,
    start: int,
    stop: int,
    lrc_threshold: float,
    shift: float,
    right_shift: float,
) -> tuple[float, float]:  # pragma: no cover - compiled
    """Pixels left-right checked and the inconsistent ones among them over ``[start, stop)``."""
    last = np.float64(coded.shape[0] - 1)
    n_lrc = 0.0
    n_bad = 0.0
    for x in range(start, stop):
        raw = coded[x]
        d = np.float64(abs(raw)) + shift
        source = x - d
        target = int(min(max(source, 0.0), last) + 0.5)
        other = right_coded[target]
        checked = (raw > floor) & (source >= 0.0) & (source <= last) & (other > floor)
        n_lrc += 1.0 if checked else 0.0
        other_d = np.float64(abs(other)) + right_shift
        n_bad += 1.0 if checked & (abs(d - other_d) > lrc_threshold) else 0.0
    return n_lrc, n_bad


@dataclass(frozen=True)
class ImagePair:
    """The left and right rectified images of one frame with their GT-free partition.

    Build it once per frame with :meth:`GroundTruthFree.pair` and score every method on it.
    """

    left: np.ndarray
    right: np.ndarray
    partition: crit.Partition
    right_pairs: np.ndarray
    """Both interpolation neighbours of every right pixel (:func:`neighbour_pairs`)."""
    runs: tuple[np.ndarray, np.ndarray, np.ndarray]
    """Runs of equal cells along the rows (:func:`cell_runs`)."""

    @property
    def shape(self) -> tuple[int, int]:
        """Image size (rows, columns)."""
        return self.partition.shape


class GroundTruthFree:
    """Scores estimated disparity maps by the images alone (``vpe``, ``lrc``, ``density``).

    >>> free = GroundTruthFree(("all", "texture"))
    >>> scores = free.score(free.pair(left, right), est)  # doctest: +SKIP
    >>> scores["gtfree:textured"]["vpe"]  # doctest: +SKIP
    """

    def __init__(
        self,
        criteria: Sequence[str] = DEFAULT_GT_FREE_CRITERIA,
        missing: str = "interpolate",
        *,
        roi_names: Mapping[int, str] | None = None,
        texture_window: int = crit.TEXTURE_WINDOW,
        texture_threshold: float = crit.TEXTURE_THRESHOLD,
        occlusion_tolerance: float = OCCLUSION_TOLERANCE,
        lrc_threshold: float = LRC_THRESHOLD,
    ) -> None:
        if isinstance(criteria, str):
            criteria = (criteria,)
        chosen = tuple(dict.fromkeys(criteria))
        unknown = [c for c in chosen if c not in GT_FREE_CRITERION_SETS]
        if unknown or not chosen:
            raise ConfigurationError(
                f"unknown ground-truth-free criterion set '{', '.join(unknown) or '(none)'}'; "
                f"choose from {', '.join(GT_FREE_CRITERION_SETS)}"
            )
        if missing not in POLICIES:
            raise ConfigurationError(
                f"unknown missing-estimate policy '{missing}'; choose from {', '.join(POLICIES)}"
            )
        self.criteria = chosen
        self.missing = missing
        self.roi_names = dict(roi_names) if roi_names else None
        self.texture_window = int(texture_window)
        self.texture_threshold = float(texture_threshold)
        if not occlusion_tolerance >= 0:
            raise ConfigurationError(
                f"the occlusion tolerance must be at least 0 px, got {occlusion_tolerance}"
            )
        self.occlusion_tolerance = float(occlusion_tolerance)
        self.lrc_threshold = float(lrc_threshold)
        self.thresholds = thresholds_for(GT_FREE_SCORED, 1.0)
        self._local = threading.local()
        self._criteria_cache: (
            tuple[
                np.ndarray,
                np.ndarray | None,
                crit.Partition,
                tuple[np.ndarray, np.ndarray, np.ndarray],
            ]
            | None
        ) = None

    def pair(self, left: object, right: object, roi: np.ndarray | None = None) -> ImagePair:
        """Check the images and build the GT-free criteria from the left one (once per frame).

        The criteria of the last left image (and ROI) are kept and compared by content: a
        left image seen again (several estimates of one scene, a repeated frame) reuses them.
        """
        left8 = grey8(left, "the left image")
        right8 = grey8(right, "the right image")
        if left8.shape[1] < 2:
            raise InputError(f"the images are {left8.shape[1]} px wide: at least 2 are needed")
        if left8.shape != right8.shape:
            raise ShapeMismatchError(
                f"the right image is {right8.shape[1]}×{right8.shape[0]} but the left image is "
                f"{left8.shape[1]}×{left8.shape[0]}"
            )
        roi_array = None if roi is None else np.asarray(roi)
        cached = self._criteria_cache
        if cached is not None and _same(cached[0], left8) and _same(cached[1], roi_array):
            partition, runs = cached[2], cached[3]
        else:
            partition = self._partition(left8, roi_array)
            runs = cell_runs(partition.cells)
            kept = None if roi_array is None else roi_array.copy()
            self._criteria_cache = (left8.copy(), kept, partition, runs)
        return ImagePair(left8, right8, partition, neighbour_pairs(right8), runs)

    def _partition(self, left8: np.ndarray, roi: np.ndarray | None) -> crit.Partition:
        """The GT-free criteria of one left image (and region of interest)."""
        everywhere = np.ones(left8.shape, bool)
        sets = []
        for name in self.criteria:
            if name == "all":
                sets.append(crit.all_set(everywhere))
            elif name == "texture":
                sets.append(crit.texture_set(left8, self.texture_window, self.texture_threshold))
            elif roi is None:
                raise ConfigurationError(
                    "the 'roi' criterion set needs a region-of-interest mask or label image"
                )
            else:
                sets.append(crit.roi_set(everywhere, roi, self.roi_names))
        return crit.build_partition(everywhere, sets)

    def score(
        self,
        pair: ImagePair,
        est: np.ndarray,
        *,
        est_range: tuple[float, float] | None = None,
        est_right: np.ndarray | None = None,
        right_range: tuple[float, float] | None = None,
        est_offset: float = 0.0,
    ) -> Scores:
        """Score one estimate on ``gtfree:`` criteria (``lrc`` only with ``est_right``).

        Validity and ``est_offset`` (both views') as :meth:`Evaluator.score` reads them.
        """
        coded, shift = self._coded("left", est, est_range, est_offset, pair.shape, "the estimate")
        right_coded, right_shift = (
            (np.zeros((0, 0), np.float32), 0.0)
            if est_right is None
            else self._coded(
                "right", est_right, right_range, est_offset, pair.shape, "the right-view estimate"
            )
        )
        partition = pair.partition
        sums = np.zeros((partition.offsets.shape[0] - 1, FIELDS), dtype=np.float64)
        photometric_sums(
            pair.left,
            pair.right_pairs,
            coded,
            self.missing != "ignore",
            pair.runs,
            right_coded,
            self.occlusion_tolerance,
            self.lrc_threshold,
            partition.cells,
            sums,
            shift,
            right_shift,
        )
        return Scores(
            criteria=tuple(GT_FREE_PREFIX + name for name in partition.criteria),
            measures=GT_FREE_SCORED,
            sums=partition.membership.astype(np.float64) @ sums,
            thresholds=self.thresholds,
            relative=True,
            policy=self.missing,
        )

    def criterion_names(self) -> tuple[str, ...]:
        """The ``gtfree:`` criteria every scored frame has, in order (known without images)."""
        names: list[str] = []
        for name in self.criteria:
            if name == "all":
                names.append("all")
            elif name == "texture":
                names.extend(crit.TEXTURE)
            elif self.roi_names:
                names.extend((*(self.roi_names[v] for v in sorted(self.roi_names)), "unlabelled"))
            else:
                names.extend(("roi", "elsewhere"))
        return tuple(GT_FREE_PREFIX + name for name in dict.fromkeys(names))

    def empty(self) -> Scores:
        """Scores of a frame whose images could not be used: the criteria with zero sums."""
        criteria = self.criterion_names()
        return Scores(
            criteria=criteria,
            measures=GT_FREE_SCORED,
            sums=np.zeros((len(criteria), FIELDS), dtype=np.float64),
            thresholds=self.thresholds,
            relative=True,
            policy=self.missing,
        )

    def _coded(
        self,
        slot: str,
        est: np.ndarray,
        est_range: tuple[float, float] | None,
        est_offset: float,
        shape: tuple[int, int],
        what: str,
    ) -> tuple[np.ndarray, float]:
        """The estimate coded by the missing policy, in a thread buffer, and its shift.

        Validity is in the sign; ``|coded| + shift`` is the disparity ``x_l − x_r``.
        """
        estimate = as_disparity(est, what)
        if estimate.shape != shape:
            raise ShapeMismatchError(
                f"{what} is {estimate.shape[1]}×{estimate.shape[0]} but the images are "
                f"{shape[1]}×{shape[0]}"
            )
        buffer = getattr(self._local, slot, None)
        if buffer is None or buffer.shape != shape:
            buffer = np.empty(shape, dtype=np.float32)
            setattr(self._local, slot, buffer)
        lo, hi, base, shift = estimate_coding(est_range, est_offset)
        k.normalise_estimate(estimate, lo, hi, base, shift, POLICIES[self.missing], buffer)
        return buffer, shift


def joined(gt: Scores | None, free: Scores | None) -> Scores:
    """One method's GT scores and GT-free scores as one :class:`Scores` (rows side by side).

    The GT-free rows keep their ``gtfree:`` names; :class:`Scores` reports GT measures only on
    GT rows and GT-free measures only on ``gtfree:`` rows.
    """
    if gt is None or free is None:
        chosen = gt if gt is not None else free
        if chosen is None:
            raise ConfigurationError("no scores to join")
        return chosen
    if gt.policy != free.policy:
        raise ConfigurationError(
            f"GT scores under '{gt.policy}' and GT-free scores under '{free.policy}'"
        )
    return Scores(
        criteria=(*gt.criteria, *free.criteria),
        measures=tuple(dict.fromkeys((*gt.measures, *GT_FREE_MEASURES))),
        sums=np.vstack([gt.sums, free.sums]),
        thresholds=gt.thresholds,
        quantiles=dict(gt.quantiles),
        relative=gt.relative,
        overlapping=gt.overlapping,
        policy=gt.policy,
    )


def concordance(a: Sequence[float], b: Sequence[float]) -> tuple[int, int, int, int]:
    """Pairs of items ordered alike and unlike by ``a`` and ``b``, and tied in one only.

    ``(concordant, discordant, tied in a only, tied in b only)``; pairs tied in both count
    nowhere.
    """
    concordant = discordant = ties_a = ties_b = 0
    for i in range(len(a)):
        for j in range(i + 1, len(a)):
            da = np.sign(a[i] - a[j])
            db = np.sign(b[i] - b[j])
            if da == 0 and db != 0:
                ties_a += 1
            elif db == 0 and da != 0:
                ties_b += 1
            elif da * db > 0:
                concordant += 1
            elif da * db < 0:
                discordant += 1
    return concordant, discordant, ties_a, ties_b


def kendall_tau(a: Sequence[float], b: Sequence[float]) -> float:
    """Kendall's τ-b of two rankings of the same items (nan when either is constant).

    How well a GT-free measure orders methods as a GT measure does: 1 the same order, 0
    unrelated, −1 reversed. Ties in either ranking are handled (τ-b).
    """
    concordant, discordant, ties_a, ties_b = concordance(a, b)
    untied = concordant + discordant
    denominator = math.sqrt((untied + ties_b) * (untied + ties_a))
    return (concordant - discordant) / denominator if denominator else math.nan
