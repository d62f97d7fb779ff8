"""LiDAR error drift between scans: the change of a method's error along the camera's motion.

The projected scan of frame ``t`` is the reference at ``t`` (the ground truth ``eval`` scores:
z-buffered, parallax-filtered, one point per pixel). Each of its pixels ``p`` is a point: the
pixel's centre at the ground truth's depth ``Z = f·B/(dₜ(p) + doffs)``, ``P = Z·((x − cx)/f,
(y − cy)/f, 1)``. With a static world the camera's motion carries it into the camera at
``t + k`` (``Q = motion⁻¹·P``), where it lands at ``p' = (cx + f·Qx/Qz, cy + f·Qy/Qz)`` with the
expected disparity ``dₜ₊ₖ = f·B/Qz − doffs``. The **drift** at the point is the change of the
method's signed error, ``c = (d̂ₜ₊ₖ(p') − dₜ₊ₖ) − (d̂ₜ(p) − dₜ(p))``, scored as ``|c|``
(``d̂ₜ₊ₖ`` read bilinearly): TEPE along the ego-motion with the scan as ground truth. A
constant bias drifts 0; per-frame noise does not.

A point is dropped, each reason counted, as the first of these that applies (the first three
depend on the scans and the motion only, so they are the same for every method): ``behind``
(``Qz ≤ 0``); ``outside`` (``p'`` is not inside the image, where the 2×2 bilinear support
is); ``hidden`` (a point of scan ``t + k``'s own projection within the ``w × w`` window around
``p'``'s pixel is nearer by more than the relative gap ``g``: ``Z_near·(1 + g) < Qz``, the
parallax filter's test, :class:`~dispeval_ros.core.projection.CloudFilter`); ``missing`` (no
estimate at ``p``) and ``missing_target`` (a pixel of the support has none), under the
``ignore`` policy only: ``interpolate`` and ``thesis`` score the value the policy gives, as
every other measure does.

Per criterion of the reference at ``t`` the sums are the points, the count of each status,
``Σ|c|``, ``Σc²``, ``Σc`` (the bias drift: the change of the mean signed error between the
scans over the counted points) and ``Σ(d̂ₜ − dₜ)``, and ``#{|c| > X}`` per threshold: pooled
sums over a sequence are exact. Everything is pure (arrays in, sums out).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from dispeval_ros.core import criteria as crit
from dispeval_ros.core import kernels
from dispeval_ros.core.egomotion import PinholeCamera, rigid_motion
from dispeval_ros.core.evaluator import POLICIES, as_disparity, estimate_coding
from dispeval_ros.core.measures import DEFAULT_BAD_THRESHOLDS
from dispeval_ros.core.projection import CloudFilter
from dispeval_ros.core.transforms import invert_rigid
from dispeval_ros.errors import ConfigurationError, ShapeMismatchError

PREFIX = "drift:"
"""The label of the drift's criteria (``drift:all``): temporal noise, never accuracy."""
STATUS_NAMES = ("drift", "behind", "outside", "hidden", "missing", "missing_target")
"""What happened to a point of the reference at ``t``, by status code: counted, or dropped."""
BASE_COLUMNS = (
    "n",
    *(f"n_{name}" for name in STATUS_NAMES),
    "sum_abs",
    "sum_sq",
    "sum",
    "sum_error",
)
"""The sums' columns before one ``bad`` count per threshold (``|c| > threshold``)."""
LABEL = (
    "temporal noise against the LiDAR scans: the change of each point's error from scan t to "
    "scan t + k along the motion (static world); a constant bias drifts 0; not accuracy"
)
"""What every drift output says it is (the text titles and the JSON ``label``)."""
UNITS = {
    "counted": "% of the points", "mean": "px", "rms": "px", "bias_drift": "px",
    "mean_error": "px",
}  # fmt: skip
"""The units of the drift's values (``bad_X``: % of the counted points)."""
WHAT = ("scan at t", "scan at t + k", "estimate at t", "estimate at t + k")
"""The four maps of a pair, as errors name them."""
_BAD = len(BASE_COLUMNS)
"""The first ``bad`` column (the kernel writes the columns in :data:`BASE_COLUMNS`' order)."""


@dataclass(frozen=True)
class DriftOptions:
    """The missing-estimate policy, the visibility test (a :class:`CloudFilter`) and thresholds."""

    missing: str = "interpolate"
    visibility: CloudFilter = field(default_factory=CloudFilter)
    thresholds: tuple[float, ...] = DEFAULT_BAD_THRESHOLDS

    def __post_init__(self) -> None:
        if self.missing not in POLICIES:
            raise ConfigurationError(
                f"unknown missing-estimate policy '{self.missing}'; choose from "
                f"{', '.join(POLICIES)}"
            )
        if not all(isinstance(t, (int, float)) and t >= 0 for t in self.thresholds):
            raise ConfigurationError(f"drift thresholds must be ≥ 0, got {self.thresholds!r}")

    @classmethod
    def of_run(cls, missing: str, delta: float) -> DriftOptions:
        """A run's options: its missing policy, thresholds its δ and the default bad levels.

        The one rule ``eval --egomotion`` and ``dispeval bag --egomotion`` (and live) share.
        """
        return cls(missing=missing, thresholds=tuple(sorted({delta, *DEFAULT_BAD_THRESHOLDS})))

    def to_dict(self) -> dict[str, object]:
        """The JSON ``options`` of a drift entry (the visibility test as ``W,G``)."""
        return {
            "missing": self.missing,
            "visibility": str(self.visibility),
            "thresholds": list(self.thresholds),
        }


@dataclass(frozen=True)
class DriftSums:
    """Per-criterion sums of the drift: pooled by ``+``, exact over a sequence.

    ``sums[i]`` holds criterion ``criteria[i]``'s :data:`BASE_COLUMNS` then one count per
    threshold. ``maps`` (when asked for): per-pixel status (−1: not a point) and ``c`` (px).
    ``options``: what they were scored under (pooled sums must share them; stored with them).
    """

    criteria: tuple[str, ...]
    thresholds: tuple[float, ...]
    sums: np.ndarray
    maps: tuple[np.ndarray, ...] = field(default=(), compare=False, repr=False)
    options: DriftOptions | None = None

    @property
    def columns(self) -> tuple[str, ...]:
        """Names of the sums' columns."""
        return (*BASE_COLUMNS, *(f"bad_{t:g}" for t in self.thresholds))

    @classmethod
    def restored(
        cls,
        criteria: Sequence[str],
        sums: np.ndarray,
        missing: str,
        visibility: str,
        thresholds: Sequence[float],
    ) -> DriftSums:
        """Stored sums read back (a database row, a status); ValueError if they do not fit.

        ``visibility``: the hidden test as ``W,G`` (:meth:`CloudFilter.parse`).
        """
        levels = tuple(float(t) for t in thresholds)
        table = np.asarray(sums, dtype=np.float64)
        if not criteria or table.size != len(criteria) * (len(BASE_COLUMNS) + len(levels)):
            raise ValueError(f"{table.size} drift sums do not fit {len(criteria)} criteria")
        try:
            options = DriftOptions(missing, CloudFilter.parse(visibility), levels)
        except ConfigurationError as error:
            raise ValueError(str(error)) from None
        return cls(tuple(criteria), levels, table.reshape(len(criteria), -1).copy(), (), options)

    def __add__(self, other: DriftSums) -> DriftSums:
        mine, theirs = (self.criteria, self.thresholds), (other.criteria, other.thresholds)
        if mine != theirs or self.options != other.options:
            raise ConfigurationError(
                f"cannot pool drift sums over {', '.join(other.criteria)} with drift sums over "
                f"{', '.join(self.criteria)} (or other thresholds or options)"
            )
        return DriftSums(self.criteria, self.thresholds, self.sums + other.sums, (), self.options)

    def summary(self, criterion: str) -> dict[str, float]:
        """Counts and values of one criterion (NaN where no point was counted).

        ``counted`` (% of the points), ``mean`` (of ``|c|``), ``rms``, ``bias_drift`` (mean
        ``c``) and ``mean_error`` (mean ``d̂ₜ − dₜ`` of the counted points) in px; ``bad_X`` in
        % of the counted points.
        """
        row = dict(zip(self.columns, self.sums[self.criteria.index(criterion)], strict=True))
        n = row["n_drift"]
        out = {name: float(row[name]) for name in BASE_COLUMNS[: 1 + len(STATUS_NAMES)]}

        def per(value: float) -> float:
            return float(value / n) if n else math.nan

        out["counted"] = float(100.0 * n / row["n"]) if row["n"] else math.nan
        out["mean"] = per(row["sum_abs"])
        out["rms"] = math.sqrt(per(row["sum_sq"])) if n else math.nan
        out["bias_drift"] = per(row["sum"])
        out["mean_error"] = per(row["sum_error"])
        for t in self.thresholds:
            out[f"bad_{t:g}"] = 100.0 * per(row[f"bad_{t:g}"])
        return out


def drift_entry(options: DriftOptions, drift: Mapping[str, DriftSums | None]) -> dict[str, object]:
    """The ``lidar_drift`` JSON entry: label, options, units, per method values and sums.

    Values and sums by ``drift:`` criterion (None: no pair scored). ``eval --egomotion
    --json`` and the bag's summary.json both write it, so they read alike.
    """
    methods: dict[str, object] = {}
    for name, pooled in drift.items():
        if pooled is None:
            methods[name] = {"criteria": None, "sums": None}
            continue
        labels = [PREFIX + c for c in pooled.criteria]
        methods[name] = {
            "criteria": {
                n: pooled.summary(c) for n, c in zip(labels, pooled.criteria, strict=True)
            },
            "sums": {
                n: dict(zip(pooled.columns, row.tolist(), strict=True))
                for n, row in zip(labels, pooled.sums, strict=True)
            },
        }
    return {
        "measure": "lidar_drift",
        "label": LABEL,
        "options": options.to_dict(),
        "units": {**UNITS, **{f"bad_{t:g}": "%" for t in options.thresholds}},
        "methods": methods,
    }


def coded_estimate(estimate: object, missing: str, what: str = "the estimate") -> np.ndarray:
    """An estimate with the policy applied, validity in the sign (``> 0``: valid; ``|v|``: value).

    Missing: not finite or ``≤ 0``. Done once per frame, used by both pairs the frame is in.
    """
    if missing not in POLICIES:
        raise ConfigurationError(
            f"unknown missing-estimate policy '{missing}'; choose from {', '.join(POLICIES)}"
        )
    disparity = as_disparity(estimate, what)
    lo, hi, base, shift = estimate_coding(None)
    out = np.empty_like(disparity)
    kernels.normalise_estimate(disparity, lo, hi, base, shift, POLICIES[missing], out)
    return out


def lidar_drift(
    reference: np.ndarray,
    target_reference: np.ndarray,
    estimate: np.ndarray,
    target_estimate: np.ndarray,
    motion: object,
    camera: PinholeCamera,
    partition: crit.Partition | None = None,
    options: DriftOptions | None = None,
    *,
    keep_maps: bool = False,
) -> DriftSums:
    """The drift of one method over one pair of scans (``t`` and ``t + k``).

    ``reference``, ``target_reference``: the projected scans of ``t`` and ``t + k`` (disparity,
    ``> 0`` where a point is); ``estimate``, ``target_estimate``: the method's maps at ``t`` and
    ``t + k`` coded by :func:`coded_estimate` under ``options.missing``. ``motion``: the pose of
    the left camera at ``t + k`` in its frame at ``t`` (4×4,
    :func:`~dispeval_ros.core.egomotion.camera_motion`). ``partition``: the criteria of
    ``reference`` (pixels not evaluated: cells < 0), default ``all`` of its points.
    """
    chosen = options or DriftOptions()
    given = (reference, target_reference, estimate, target_estimate)
    maps = [_map(m, f"the {what}") for m, what in zip(given, WHAT, strict=True)]
    shape = maps[0].shape
    for array, what in zip(maps[1:], WHAT[1:], strict=True):
        if array.shape != shape:
            raise ShapeMismatchError(
                f"the {what} is {crit.size_text(array.shape)} but the scan at t is "
                f"{crit.size_text(shape)}"
            )
    if min(shape) < 2:
        raise ShapeMismatchError(f"the maps are {crit.size_text(shape)}: at least 2×2 is needed")
    if partition is None:
        order = np.flatnonzero(maps[0] > 0)
        offsets = np.array([0, order.size], np.int64)
        membership = np.ones((1, 1), bool)
        names: tuple[str, ...] = ("all",)
    else:
        if partition.shape != shape:
            raise ShapeMismatchError(
                f"the criteria are {crit.size_text(partition.shape)} but the scan at t is "
                f"{crit.size_text(shape)}"
            )
        order, offsets = partition.order, partition.offsets
        membership, names = partition.membership, partition.criteria
    rt = np.ascontiguousarray(invert_rigid(rigid_motion(motion))[:3])
    thresholds = np.asarray(chosen.thresholds, dtype=np.float64)
    sums = np.zeros((membership.shape[1], _BAD + thresholds.size), np.float64)
    status = np.full(shape if keep_maps else (0, 0), -1, np.int8)
    change = np.full(shape if keep_maps else (0, 0), np.nan, np.float32)
    visibility = chosen.visibility
    _drift(
        maps[0],
        maps[1],
        maps[2],
        maps[3],
        np.ascontiguousarray(order, dtype=np.int64),
        np.ascontiguousarray(offsets, dtype=np.int64),
        rt,
        camera.geometry(),
        visibility.window,
        float(visibility.gap),
        chosen.missing == "ignore",
        thresholds,
        sums,
        status,
        change,
    )
    return DriftSums(
        names,
        tuple(float(t) for t in chosen.thresholds),
        membership.astype(np.float64) @ sums,
        (status, change) if keep_maps else (),
        chosen,
    )


def _map(values: np.ndarray, what: str) -> np.ndarray:
    return np.ascontiguousarray(as_disparity(values, what), dtype=np.float32)


@njit(cache=True, nogil=True)
def _drift(
    gt: np.ndarray,
    gt_next: np.ndarray,
    est: np.ndarray,
    est_next: np.ndarray,
    order: np.ndarray,
    offsets: np.ndarray,
    rt: np.ndarray,
    geo: np.ndarray,
    window: int,
    gap: float,
    ignore: bool,
    thresholds: np.ndarray,
    sums: np.ndarray,
    status: np.ndarray,
    change: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Every point of ``gt`` moved, tested and, when counted, its drift summed (the module).

    The points are ``order[offsets[c]:offsets[c + 1]]`` (flat pixel indices) for cell ``c``.
    """
    height, width = gt.shape
    f, cx, cy, fb, doffs = geo[0], geo[1], geo[2], geo[3], geo[4]
    half = window // 2
    keep = status.shape[0] > 0
    bounds = _block_maxima(gt_next) if window > 1 else np.zeros((0, 0), np.float32)
    columns = np.uint64(width)
    for cell in range(offsets.size - 1):
        row = sums[cell]
        for point in range(offsets[cell], offsets[cell + 1]):
            flat = np.uint64(order[point])  # unsigned: no negative-index wrap on every read
            y = flat // columns
            x = flat - y * columns
            d = np.float64(gt[y, x])
            if not d > 0.0:
                continue
            row[0] += 1.0
            code = 1  # behind
            c = 0.0
            s = d + doffs
            if s > 0.0:
                z = fb / s
                px, py = z * (x - cx) / f, z * (y - cy) / f
                qx = rt[0, 0] * px + rt[0, 1] * py + rt[0, 2] * z + rt[0, 3]
                qy = rt[1, 0] * px + rt[1, 1] * py + rt[1, 2] * z + rt[1, 3]
                qz = rt[2, 0] * px + rt[2, 1] * py + rt[2, 2] * z + rt[2, 3]
                if qz > 0.0:
                    code = 2  # outside
                    u = cx + f * qx / qz
                    v = cy + f * qy / qz
                    if 0.0 <= u <= width - 1.0 and 0.0 <= v <= height - 1.0:
                        code = _visible(gt_next, bounds, u, v, qz, fb, doffs, half, window, gap)
                        if code == 0:
                            e = est[y, x]
                            if ignore and not e > 0.0:
                                code = 4  # missing
                        if code == 0:
                            x0 = np.uint64(min(math.floor(u), width - 2))
                            y0 = np.uint64(min(math.floor(v), height - 2))
                            one = np.uint64(1)
                            ax, ay = u - x0, v - y0
                            a, b = est_next[y0, x0], est_next[y0, x0 + one]
                            g, h = est_next[y0 + one, x0], est_next[y0 + one, x0 + one]
                            if ignore and not (a > 0.0 and b > 0.0 and g > 0.0 and h > 0.0):
                                code = 5  # missing_target
                            else:
                                top = (1.0 - ax) * abs(a) + ax * abs(b)
                                bottom = (1.0 - ax) * abs(g) + ax * abs(h)
                                moved = (1.0 - ay) * top + ay * bottom
                                error = abs(np.float64(est[y, x])) - d
                                c = (moved - (fb / qz - doffs)) - error
                                row[7] += abs(c)
                                row[8] += c * c
                                row[9] += c
                                row[10] += error
                                for i in range(thresholds.size):
                                    row[11 + i] += np.float64(abs(c) > thresholds[i])
            row[1 + code] += 1.0
            if keep:
                status[y, x] = code
                if code == 0:
                    change[y, x] = c


BLOCK = 8
"""The side of the blocks whose largest disparity bounds a window's (see :func:`_visible`)."""


@njit(cache=True, nogil=True)
def _block_maxima(gt_next: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """The largest disparity of each :data:`BLOCK` × :data:`BLOCK` block (0: no point).

    A NaN is no point (``v > m`` is false), as in :func:`_visible`. Rows are reduced first
    (elementwise over whole rows: vectorised), then each block's columns.
    """
    height, width = gt_next.shape
    rows, cols = (height + BLOCK - 1) // BLOCK, (width + BLOCK - 1) // BLOCK
    out = np.empty((rows, cols), np.float32)
    column = np.empty(width, np.float32)
    size = np.uint64(width)
    for block in range(rows):
        column[:] = 0.0
        for r in range(block * BLOCK, min(block * BLOCK + BLOCK, height)):
            source = gt_next[r]
            for k in range(size):
                value, largest = source[k], column[k]
                column[k] = value if value > largest else largest
        target = out[block]
        for j in range(cols):
            largest = np.float32(0.0)
            for k in range(np.uint64(j * BLOCK), np.uint64(min(j * BLOCK + BLOCK, width))):
                value = column[k]
                largest = value if value > largest else largest
            target[j] = largest
    return out


@njit(cache=True, nogil=True)
def _hides(
    largest: float, qz: float, fb: float, doffs: float, gap: float
) -> bool:  # pragma: no cover - compiled
    """Whether a point of disparity ``largest`` is nearer than ``qz`` by more than ``gap``."""
    s = np.float64(largest) + doffs
    return largest > 0.0 and s > 0.0 and (fb / s) * (1.0 + gap) < qz


@njit(cache=True, nogil=True)
def _visible(
    gt_next: np.ndarray,
    bounds: np.ndarray,
    u: float,
    v: float,
    qz: float,
    fb: float,
    doffs: float,
    half: int,
    window: int,
    gap: float,
) -> int:  # pragma: no cover - compiled
    """0 when no point of the next scan near the landing is nearer by more than ``gap``, else 3.

    The nearest point is the largest disparity: one division (``f·B/s`` is monotone in ``s``
    in floating point too, so this is the test of every point of the window, bit for bit).
    The same monotony makes the blocks covering the window (``bounds``, their largest
    disparities) a test that can only say yes too often: the window itself is read only
    where they hide the point (about one landing in five on the shared drive).
    """
    if window < 1:
        return 0
    height, width = gt_next.shape
    col, line = math.floor(u + 0.5), math.floor(v + 0.5)
    top, bottom = max(line - half, 0), min(line + half + 1, height)
    left, right = np.uint64(max(col - half, 0)), np.uint64(min(col + half + 1, width))
    if window > 1:
        bound = np.float32(0.0)
        first, last = left // np.uint64(BLOCK), (right - np.uint64(1)) // np.uint64(BLOCK)
        for block in range(top // BLOCK, (bottom - 1) // BLOCK + 1):
            source = bounds[block]
            for j in range(first, last + np.uint64(1)):
                value = source[j]
                bound = value if value > bound else bound
        if not _hides(bound, qz, fb, doffs, gap):
            return 0
    largest = np.float32(0.0)
    for r in range(top, bottom):
        source = gt_next[r]
        for k in range(left, right):
            value = source[k]
            largest = value if value > largest else largest  # a NaN is no point
    return 3 if _hides(largest, qz, fb, doffs, gap) else 0
