"""Official benchmark protocols: MiddEval3, KITTI 2015, KITTI 2012 and ETH3D, exactly.

Each protocol is a preset of regions, measures, thresholds, invalid-estimate handling and the
official tool's arithmetic, so that a user's numbers can be put beside a leaderboard's. The
project's own measures (:mod:`dispeval_ros.core.measures`) keep exact arithmetic; here every
step the official tool does in ``float`` (float32) is done in float32 too, because that is
what the leaderboard shows:

- MiddEval3 SDK ``evaldisp``: ``err = |d − gt|`` in float32, the error sum ``serr`` accumulated
  in a float32 in row-major order, the percentages stored in a float; invalid = ``INF`` only,
  valid estimates clipped to ``[0, ndisp]``.
- KITTI 2015 devkit (``evaluate_scene_flow.cpp``): ``e = |d_gt − d_ipol|`` and ``e/|d_gt|`` in
  float32, the quotient compared with the double ``0.05`` (so an error of exactly 5 % is an
  outlier); per-frame ratios in float32; pooled counters summed in float32 (they exceed 2²⁴).
- KITTI 2012 devkit (``evaluate_stereo.cpp``): ``e`` in float32, the error sum in a float32 in
  column-major order (``u`` outer, ``v`` inner), the summary a float32 mean of per-frame values.
- ETH3D two-view evaluation: ``e = d − gt`` in float32, sums in double of float32 terms, the
  quantile index ``floor(N·q)`` with ``N·q`` in float32, ``rms = sqrtf(…)``.

KITTI's background interpolation leaves rows without any estimate between estimated rows at −1
(and the whole map when nothing is estimated); :func:`kitti_interpolation` does the same.
Nothing here reads files: the dataset trees are found by :mod:`dispeval_ros.io.benchmarks`.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from dispeval_ros.core import kernels
from dispeval_ros.core.evaluator import as_disparity
from dispeval_ros.errors import ConfigurationError, ShapeMismatchError

F32 = np.float32

#: MiddEval3 training scenes and the weights of the weighted average of the training table:
#: the radiometric / rectification variants of a scene that is also in the set (``E``, ``L``,
#: ``P``) count half. Scenes not listed (e.g. test scenes) get weight 1.
MIDDEVAL3_WEIGHTS: dict[str, float] = {
    "Adirondack": 1.0,
    "ArtL": 1.0,
    "Jadeplant": 1.0,
    "Motorcycle": 1.0,
    "MotorcycleE": 0.5,
    "Piano": 1.0,
    "PianoL": 0.5,
    "Pipes": 1.0,
    "Playroom": 1.0,
    "Playtable": 1.0,
    "PlaytableP": 0.5,
    "Recycle": 1.0,
    "Shelves": 1.0,
    "Teddy": 1.0,
    "Vintage": 1.0,
}


@dataclass(frozen=True)
class Protocol:
    """One benchmark's evaluation preset.

    ``regions`` and ``columns`` are the official names in the official order; ``percent``
    lists the columns shown as percentages; ``objectives`` are the lower-is-better columns the
    A* Groups compare; ``summary`` says how frames are combined; ``float32`` where the official
    tool's float32 arithmetic is reproduced.
    """

    name: str
    title: str
    tool: str
    regions: tuple[str, ...]
    columns: tuple[str, ...]
    percent: tuple[str, ...]
    objectives: tuple[str, ...]
    summary: str
    float32: str
    settings: Mapping[str, object] = field(default_factory=dict)

    def record(self) -> dict[str, object]:
        """Everything that defines the protocol's numbers, as plain values."""
        return {
            "protocol": self.name,
            "tool": self.tool,
            "regions": list(self.regions),
            "columns": list(self.columns),
            "summary": self.summary,
            "float32": self.float32,
            "settings": dict(self.settings),
        }

    def sha256(self) -> str:
        """Hash of :meth:`record` (canonical JSON), to name the configuration in results."""
        return config_sha256(self.record())


def config_sha256(record: Mapping[str, object]) -> str:
    """sha256 of a configuration record as canonical JSON (sorted keys, no spaces)."""
    text = json.dumps(record, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


_QUANTILES = (50, 90, 95, 99)
_BAD = (0.5, 1.0, 2.0, 4.0)
_BAD_COLUMNS = tuple(f"bad {t:.1f}" for t in _BAD)
_QUANTILE_COLUMNS = tuple(f"A{q}" for q in _QUANTILES)


_D1 = ("D1-bg", "D1-fg", "D1-all")
_OUT = tuple(f"Out-{k}" for k in (2, 3, 4, 5))
_KITTI_INTERPOLATION = "devkit interpolateBackground (rows without estimate stay -1)"


def _kitti_columns(main: tuple[str, ...]) -> tuple[str, ...]:
    """KITTI's columns: each over all GT pixels, then over estimated pixels (est), density."""
    return (*main, *(f"{c} (est)" for c in main), "density")


def _error_columns(average: str) -> tuple[str, ...]:
    """The Middlebury-style error columns (MiddEval3 and ETH3D name the mean differently)."""
    return (*_BAD_COLUMNS, average, "rms", *_QUANTILE_COLUMNS)


PROTOCOLS: dict[str, Protocol] = {
    "middeval3": Protocol(
        name="middeval3",
        title="Middlebury MiddEval3",
        tool="MiddEval3 SDK evaldisp (runeval)",
        regions=("nonocc", "all"),
        columns=(*_BAD_COLUMNS, "invalid", *_error_columns("avgErr")[len(_BAD) :]),
        percent=(*_BAD_COLUMNS, "invalid"),
        objectives=_error_columns("avgErr"),
        summary="weighted average over scenes (MIDDEVAL3_WEIGHTS)",
        float32="err, the error sums (row-major) and the stored percentages are float32",
        settings={
            "bad_thresholds": list(_BAD),
            "bad_counts_invalid": True,
            "invalid": "+inf estimate",
            "clip": "valid estimates to [0, ndisp] (scaled with the GT)",
            "avgErr_rms_quantiles_over": "valid estimates",
            "quantile_index": "floor(float32(N) * float32(q))",
            "weights": MIDDEVAL3_WEIGHTS,
        },
    ),
    "kitti2015": Protocol(
        name="kitti2015",
        title="KITTI 2015 stereo",
        tool="KITTI 2015 devkit evaluate_scene_flow (disparityErrorsOutlier)",
        regions=("noc", "occ"),
        columns=_kitti_columns(_D1),
        percent=_kitti_columns(_D1),
        objectives=_D1,
        summary="pooled counts over frames (float32 accumulators, as the devkit)",
        float32="e and e/|d| in float32 (compared with the double 0.05), ratios and pooled "
        "counters in float32",
        settings={
            "abs_thresh": 3.0,
            "rel_thresh": 0.05,
            "interpolation": _KITTI_INTERPOLATION,
            "foreground": "obj_map > 0",
        },
    ),
    "kitti2012": Protocol(
        name="kitti2012",
        title="KITTI 2012 stereo",
        tool="KITTI 2012 devkit evaluate_stereo (disparityErrorsOutlier/Average)",
        regions=("noc", "occ"),
        columns=_kitti_columns((*_OUT, "Avg")),
        percent=tuple(c for c in _kitti_columns((*_OUT, "Avg")) if not c.startswith("Avg")),
        objectives=(*_OUT, "Avg"),
        summary="float32 mean of the per-frame values (statMean)",
        float32="e in float32, the error sum in float32 in column-major order, the means in float32",
        settings={"thresholds": [2, 3, 4, 5], "interpolation": _KITTI_INTERPOLATION},
    ),
    "eth3d": Protocol(
        name="eth3d",
        title="ETH3D two-view",
        tool="ETH3D two-view-evaluation (ComputeMetrics)",
        regions=("nonocc", "all"),
        columns=(*_error_columns("avgerr"), "coverage"),
        percent=(*_BAD_COLUMNS, "coverage"),
        objectives=_error_columns("avgerr"),
        summary="mean of the per-frame values",
        float32="e = d - gt in float32, squared errors in float32 summed in double, "
        "rms = sqrtf, quantile index floor(float32(N) * q_f)",
        settings={
            "bad_thresholds": list(_BAD),
            "estimate_valid": "finite and -width <= d <= width",
            "gt_valid": "finite",
            "measures_over": "pixels with an estimate",
        },
    ),
}


def get_protocol(name: str) -> Protocol:
    """The protocol called ``name`` or a one-line error listing the known ones."""
    try:
        return PROTOCOLS[name]
    except KeyError:
        raise ConfigurationError(
            f"unknown protocol '{name}'; choose from {', '.join(PROTOCOLS)}"
        ) from None


@dataclass
class FrameResult:
    """One method on one frame: ``values[region][column]`` in leaderboard units.

    ``counts`` holds what the summary combines (the raw counters of KITTI 2015), ``notes``
    what could not be evaluated and why (a missing ``disp_noc``, no ``obj_map``...), ``exact``
    the same frame in exact (float64) arithmetic, to tell where float32 moves a digit.
    """

    frame: str
    values: dict[str, dict[str, float]]
    counts: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    exact: FrameResult | None = None

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form (nan for the JSON writer to turn into null)."""
        return {"frame": self.frame, "regions": self.values, "notes": self.notes}


# ------------------------------------------------------------------------------ helpers


def _same_shape(gt: np.ndarray, other: np.ndarray, what: str) -> None:
    if other.shape != gt.shape:
        raise ShapeMismatchError(
            f"{what} is {other.shape[1]}×{other.shape[0]} but the ground truth is "
            f"{gt.shape[1]}×{gt.shape[0]}"
        )


def float32_sum(values: np.ndarray) -> np.float32:
    """Sequential float32 sum (``float s = 0; s += v`` in the given order), not pairwise."""
    if values.size == 0:
        return F32(0.0)
    return np.add.accumulate(values.astype(F32, copy=False), dtype=F32)[-1]


def float64_sum(values: np.ndarray) -> float:
    """Sequential double sum (``double s = 0; s += v``) of the given terms in order."""
    if values.size == 0:
        return 0.0
    return float(np.add.accumulate(values.astype(np.float64), dtype=np.float64)[-1])


def quantile_index(size: int, level: float) -> int:
    """``floor(size * level_f)`` with the product in float32, as ETH3D indexes its quantiles."""
    return math.floor(F32(F32(size) * F32(level)))


def kitti_interpolation(estimate: np.ndarray) -> np.ndarray:
    """The KITTI devkits' ``interpolateBackground`` of an estimate (invalid: not finite or ≤ 0).

    Per row, gaps between two valid pixels take the smaller of the two, then the row is
    extended to both ends; per column, the first and last filled rows are copied upwards and
    downwards. A row with no valid pixel between filled rows stays −1, as in the devkit.
    """
    estimate = np.ascontiguousarray(estimate, dtype=F32)
    coded = np.empty_like(estimate)
    kernels.normalise_estimate(
        estimate, kernels.POSITIVE, math.inf, 0.0, 0.0, kernels.POLICY_INTERPOLATE, coded
    )
    filled = np.abs(coded)
    with np.errstate(invalid="ignore"):
        has_valid = (np.isfinite(estimate) & (estimate > 0)).any(axis=1)
    rows = np.flatnonzero(has_valid)
    if rows.size == 0:
        filled[:] = -1.0
        return filled
    inner = np.zeros(estimate.shape[0], bool)
    inner[rows[0] : rows[-1] + 1] = True
    filled[inner & ~has_valid] = -1.0
    return filled


def _estimate_valid(estimate: np.ndarray) -> np.ndarray:
    """KITTI: an estimate is valid when its PNG value is > 0 (finite and > 0 here)."""
    with np.errstate(invalid="ignore"):
        return np.isfinite(estimate) & (estimate > 0)


def _ratio32(numerator: float, denominator: float) -> float:
    """``numerator / max(denominator, 1.0f)`` in float32, as the KITTI devkits normalise."""
    return float(F32(numerator) / max(F32(denominator), F32(1.0)))


@dataclass(frozen=True)
class Arithmetic:
    """The official tools' float32 steps (:data:`OFFICIAL`) or exact float64 ones (:data:`EXACT`).

    Every protocol runs in both, so the report can say where float32 moves a printed digit.
    """

    official: bool

    @property
    def real(self) -> type[np.floating]:
        """The type of per-pixel errors and of the quantities the tool keeps in a float."""
        return F32 if self.official else np.float64

    def accumulate(self, values: np.ndarray) -> np.floating:
        """A sum the tool accumulates in a float (sequential float32), else an exact sum."""
        if self.official:
            return float32_sum(values)
        return np.float64(np.sum(values, dtype=np.float64))

    def ratio(self, numerator: float, denominator: float) -> float:
        """A count ratio as the KITTI devkits normalise it (float32), else in double."""
        if self.official:
            return _ratio32(numerator, denominator)
        return float(numerator) / max(float(denominator), 1.0)

    def index(self, size: int, percent: int) -> int:
        """The quantile index ``floor(N·q)``: float32 product, else exact."""
        return quantile_index(size, percent / 100.0) if self.official else size * percent // 100

    def root(self, value: float) -> float:
        """``sqrtf`` of a value stored in a float, else an exact square root."""
        return float(np.sqrt(F32(value))) if self.official else math.sqrt(value)


OFFICIAL = Arithmetic(official=True)
EXACT = Arithmetic(official=False)


# ---------------------------------------------------------------------------- MiddEval3


def middeval3_frame(
    frame: str,
    gt: np.ndarray,
    estimate: np.ndarray,
    nonocc: np.ndarray | None,
    ndisp: float | None,
    arithmetic: Arithmetic = OFFICIAL,
) -> FrameResult:
    """MiddEval3 ``evaldisp`` over ``nonocc`` (mask value 255) and ``all`` (known GT).

    ``estimate`` may be 1/2 or 1/4 of the GT size (upsampled and scaled as the SDK does);
    ``ndisp`` (the GT's calib.txt) bounds valid estimates, ``None`` = the SDK default 99999.
    The SDK takes the bound at the result's resolution: MiddEval3 halves ``ndisp`` per level,
    rounding up (F 290, H 145, Q 73), so a result at 1/s of the GT uses ``ceil(ndisp / s)``.
    """
    gt = as_disparity(gt, "the ground truth")
    estimate = as_disparity(estimate, "the estimate")
    scale = gt.shape[1] // max(estimate.shape[1], 1)
    if (
        scale not in (1, 2, 4)
        or estimate.shape[0] * scale != gt.shape[0]
        or (estimate.shape[1] * scale != gt.shape[1])
    ):
        raise ShapeMismatchError(
            f"the estimate is {estimate.shape[1]}×{estimate.shape[0]} but the ground truth is "
            f"{gt.shape[1]}×{gt.shape[0]}; MiddEval3 needs the GT size exactly 1, 2 or 4 times it"
        )
    d = np.repeat(np.repeat(estimate, scale, axis=0), scale, axis=1) * F32(scale)
    known = ~np.isposinf(gt)
    valid = ~np.isposinf(d)
    maxdisp = 99999 if ndisp is None else math.ceil(ndisp / scale)
    maxd = F32(scale * maxdisp)
    with np.errstate(invalid="ignore"):
        d = np.where(valid, np.clip(d, F32(0.0), maxd), d).astype(F32)
        real = arithmetic.real
        error = np.abs(d.astype(real) - gt.astype(real)).astype(real)
    regions: dict[str, np.ndarray] = {}
    if nonocc is not None:
        _same_shape(gt, np.asarray(nonocc), "the nonocc mask (mask0nocc.png)")
        regions["nonocc"] = known & (np.asarray(nonocc) == 255)
    regions["all"] = known
    result = FrameResult(frame, {})
    if nonocc is None:
        result.notes.append("nonocc: no mask0nocc.png")
    for region, where in regions.items():
        result.values[region] = _middeval3_region(error, valid, where, arithmetic)
    return result


def _middeval3_region(
    error: np.ndarray, valid: np.ndarray, where: np.ndarray, arithmetic: Arithmetic
) -> dict[str, float]:
    n = int(np.count_nonzero(where))
    scored = where & valid
    invalid = n - int(np.count_nonzero(scored))
    errors = error[scored]  # row-major: the SDK's loop order
    values: dict[str, float] = {}
    real = arithmetic.real
    with np.errstate(invalid="ignore", divide="ignore"):
        for threshold in _BAD:
            bad = int(np.count_nonzero(errors > real(threshold)))
            values[f"bad {threshold:.1f}"] = (
                float(real(100.0 * (bad + invalid) / n)) if n else math.nan
            )
        values["invalid"] = float(real(100.0 * invalid / n)) if n else math.nan
        used = n - invalid
        total = arithmetic.accumulate(errors)
        values["avgErr"] = float(total / real(used)) if used else math.nan
        squares = arithmetic.accumulate((errors * errors).astype(real))
        values["rms"] = float(np.sqrt(squares / real(used))) if used else math.nan
    values.update(_quantiles(errors, arithmetic))
    return values


def _quantiles(errors: np.ndarray, arithmetic: Arithmetic = OFFICIAL) -> dict[str, float]:
    """A50…A99: the sorted errors at ``floor(N·q)`` (float32 product), NaN without errors."""
    if errors.size == 0:
        return {f"A{q}": math.nan for q in _QUANTILES}
    positions = {q: min(arithmetic.index(errors.size, q), errors.size - 1) for q in _QUANTILES}
    ordered = np.partition(errors, sorted(set(positions.values())))
    return {f"A{q}": float(ordered[p]) for q, p in positions.items()}


def middeval3_summary(
    frames: Sequence[FrameResult], weights: Mapping[str, float] | None = None
) -> dict[str, dict[str, float]]:
    """Weighted average of every column over the frames (``MIDDEVAL3_WEIGHTS`` by default)."""
    table = MIDDEVAL3_WEIGHTS if weights is None else weights
    return _weighted_mean(frames, [table.get(f.frame, 1.0) for f in frames])


def _weighted_mean(
    frames: Sequence[FrameResult], weights: Sequence[float]
) -> dict[str, dict[str, float]]:
    summary: dict[str, dict[str, float]] = {}
    regions = list(dict.fromkeys(r for f in frames for r in f.values))
    for region in regions:
        present = [
            (f.values[region], w)
            for f, w in zip(frames, weights, strict=True)
            if region in f.values
        ]
        total = sum(w for _, w in present)
        columns = list(dict.fromkeys(c for values, _ in present for c in values))
        summary[region] = {
            column: sum(values.get(column, math.nan) * w for values, w in present) / total
            if total
            else math.nan
            for column in columns
        }
    return summary


# --------------------------------------------------------------------------- KITTI 2015

_D1_COUNTERS = ("bg", "fg", "all")


def kitti2015_frame(
    frame: str,
    gt_occ: np.ndarray,
    gt_noc: np.ndarray | None,
    estimate: np.ndarray,
    obj_map: np.ndarray | None,
    arithmetic: Arithmetic = OFFICIAL,
) -> FrameResult:
    """D1 per region (``noc`` from ``disp_noc_0``, ``occ`` from ``disp_occ_0``), frame values."""
    prepared = _KittiFrame.of(frame, gt_occ, gt_noc, estimate, "disp_noc_0")
    result = prepared.result
    foreground = None
    if obj_map is not None:
        _same_shape(prepared.grounds[-1][1], np.asarray(obj_map), "the object map (obj_map)")
        foreground = np.asarray(obj_map) > 0
    else:
        result.notes.append("D1-bg/D1-fg: no obj_map (every pixel counted as background)")
    for region, gt in prepared.grounds:
        counts = _d1_counts(
            gt, prepared.interpolated, prepared.has_estimate, foreground, arithmetic
        )
        result.counts[region] = counts
        result.values[region] = kitti2015_values(counts, foreground is not None, arithmetic)
    return result


@dataclass
class _KittiFrame:
    """What both KITTI devkits prepare: the GT maps present, the interpolated estimate."""

    result: FrameResult
    grounds: list[tuple[str, np.ndarray]]
    interpolated: np.ndarray
    has_estimate: np.ndarray

    @classmethod
    def of(
        cls,
        frame: str,
        gt_occ: np.ndarray,
        gt_noc: np.ndarray | None,
        estimate: np.ndarray,
        noc_name: str,
    ) -> _KittiFrame:
        occ = as_disparity(gt_occ, "the ground truth")
        estimate = as_disparity(estimate, "the estimate")
        _same_shape(occ, estimate, "the estimate")
        result = FrameResult(frame, {})
        grounds = []
        if gt_noc is None:
            result.notes.append(f"noc: no {noc_name} ground truth")
        else:
            noc = as_disparity(gt_noc, "the noc ground truth")
            _same_shape(occ, noc, "the noc ground truth")
            grounds.append(("noc", noc))
        grounds.append(("occ", occ))
        return cls(result, grounds, kitti_interpolation(estimate), _estimate_valid(estimate))


def _d1_counts(
    gt: np.ndarray,
    interpolated: np.ndarray,
    has_estimate: np.ndarray,
    foreground: np.ndarray | None,
    arithmetic: Arithmetic,
) -> list[float]:
    """The devkit's 12 counters: (errors, pixels, errors est, pixels est) × (bg, fg, all)."""
    valid = gt > 0
    real = arithmetic.real
    error = np.abs(gt.astype(real) - interpolated.astype(real)).astype(real)
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = (error / np.abs(gt.astype(real))).astype(real)
        outlier = valid & (error > 3.0) & (relative.astype(np.float64) > 0.05)
    fg = np.zeros(gt.shape, bool) if foreground is None else foreground
    counts: list[float] = []
    for part in (valid & ~fg, valid & fg, valid):
        counts += [
            int(np.count_nonzero(outlier & part)),
            int(np.count_nonzero(part)),
            int(np.count_nonzero(outlier & part & has_estimate)),
            int(np.count_nonzero(part & has_estimate)),
        ]
    return counts


def kitti2015_values(
    counts: Sequence[float], with_foreground: bool = True, arithmetic: Arithmetic = OFFICIAL
) -> dict[str, float]:
    """D1 columns (percent) from the 12 counters, with the devkit's float32 ratios."""
    values: dict[str, float] = {}
    ratio = arithmetic.ratio
    for index, part in enumerate(_D1_COUNTERS):
        errors, pixels, errors_est, pixels_est = counts[4 * index : 4 * index + 4]
        unknown = part != "all" and not with_foreground
        values[f"D1-{part}"] = math.nan if unknown else 100.0 * ratio(errors, pixels)
        values[f"D1-{part} (est)"] = math.nan if unknown else 100.0 * ratio(errors_est, pixels_est)
    values["density"] = 100.0 * ratio(counts[11], counts[9])
    return {column: values[column] for column in PROTOCOLS["kitti2015"].columns}


def kitti2015_summary(
    frames: Sequence[FrameResult], arithmetic: Arithmetic = OFFICIAL
) -> dict[str, dict[str, float]]:
    """Pooled D1: the counters of every frame summed in float32 accumulators, in frame order."""
    summary: dict[str, dict[str, float]] = {}
    with_foreground = all("D1-bg/D1-fg" not in " ".join(f.notes) for f in frames)
    for region in PROTOCOLS["kitti2015"].regions:
        parts = [f.counts[region] for f in frames if region in f.counts]
        if not parts:
            continue
        real = arithmetic.real
        totals = np.zeros(12, dtype=real)
        for counts in parts:
            totals = (totals + np.asarray(counts, dtype=real)).astype(real)
        summary[region] = kitti2015_values([float(v) for v in totals], with_foreground, arithmetic)
    return summary


# --------------------------------------------------------------------------- KITTI 2012


def kitti2012_frame(
    frame: str,
    gt_occ: np.ndarray,
    gt_noc: np.ndarray | None,
    estimate: np.ndarray,
    arithmetic: Arithmetic = OFFICIAL,
) -> FrameResult:
    """Out-2…5 and Avg per region, over all GT pixels and over estimated ones, density."""
    prepared = _KittiFrame.of(frame, gt_occ, gt_noc, estimate, "disp_noc")
    for region, gt in prepared.grounds:
        prepared.result.values[region] = _kitti2012_region(
            gt, prepared.interpolated, prepared.has_estimate, arithmetic
        )
    return prepared.result


def _kitti2012_region(
    gt: np.ndarray, interpolated: np.ndarray, has_estimate: np.ndarray, arithmetic: Arithmetic
) -> dict[str, float]:
    valid = gt > 0
    real = arithmetic.real
    error = np.abs(gt.astype(real) - interpolated.astype(real)).astype(real)
    # the devkit loops u (columns) outside, v (rows) inside: transpose for that order
    by_column = error.T[valid.T]
    by_column_est = error.T[(valid & has_estimate).T]
    n, n_est = by_column.size, by_column_est.size
    ratio = arithmetic.ratio
    values: dict[str, float] = {}
    for k in (2, 3, 4, 5):
        values[f"Out-{k}"] = 100.0 * ratio(int(np.count_nonzero(by_column > real(k))), n)
    values["Avg"] = float(arithmetic.accumulate(by_column) / max(real(n), real(1.0)))
    for k in (2, 3, 4, 5):
        # the devkit leaves the counts unnormalised when no pixel has an estimate
        count = int(np.count_nonzero(by_column_est > real(k)))
        values[f"Out-{k} (est)"] = 100.0 * (ratio(count, n_est) if n_est else float(count))
    values["Avg (est)"] = float(arithmetic.accumulate(by_column_est) / max(real(n_est), real(1.0)))
    values["density"] = 100.0 * ratio(n_est, n)
    return {column: values[column] for column in PROTOCOLS["kitti2012"].columns}


def kitti2012_summary(
    frames: Sequence[FrameResult], arithmetic: Arithmetic = OFFICIAL
) -> dict[str, dict[str, float]]:
    """``statMean``: per column, the float32 sum of the per-frame values over float32(count)."""
    summary: dict[str, dict[str, float]] = {}
    real = arithmetic.real
    for region in PROTOCOLS["kitti2012"].regions:
        rows = [f.values[region] for f in frames if region in f.values]
        if not rows:
            continue
        summary[region] = {}
        for column in PROTOCOLS["kitti2012"].columns:
            # the devkit averages fractions; the percent scale is applied after
            scale = 100.0 if column in PROTOCOLS["kitti2012"].percent else 1.0
            terms = np.array([real(row[column] / scale) for row in rows], dtype=real)
            mean = arithmetic.accumulate(terms) / real(len(rows))
            summary[region][column] = scale * float(mean)
    return summary


# -------------------------------------------------------------------------------- ETH3D


def eth3d_frame(
    frame: str,
    gt: np.ndarray,
    estimate: np.ndarray,
    nonocc: np.ndarray | None,
    arithmetic: Arithmetic = OFFICIAL,
) -> FrameResult:
    """ETH3D ``ComputeMetrics`` for ``nonocc`` (mask value 255) and ``all`` (finite GT)."""
    gt = as_disparity(gt, "the ground truth")
    estimate = as_disparity(estimate, "the estimate")
    _same_shape(gt, estimate, "the estimate")
    width = gt.shape[1]
    known = np.isfinite(gt)
    with np.errstate(invalid="ignore"):
        estimated = np.isfinite(estimate) & (estimate <= width) & (estimate >= -width)
        real = arithmetic.real
        signed = (estimate.astype(real) - gt.astype(real)).astype(real)
    result = FrameResult(frame, {})
    regions: dict[str, np.ndarray] = {}
    if nonocc is not None:
        _same_shape(gt, np.asarray(nonocc), "the nonocc mask (mask0nocc.png)")
        regions["nonocc"] = known & (np.asarray(nonocc) == 255)
    else:
        result.notes.append("nonocc: no mask0nocc.png")
    regions["all"] = known
    for region, where in regions.items():
        result.values[region] = _eth3d_region(
            signed[where & estimated], int(np.count_nonzero(where)), arithmetic
        )
    return result


def _eth3d_region(signed: np.ndarray, n_gt: int, arithmetic: Arithmetic) -> dict[str, float]:
    size = signed.size
    values: dict[str, float] = {}
    if size == 0:
        values.update({f"bad {t:.1f}": 100.0 for t in _BAD})
        values.update({"avgerr": math.inf, "rms": math.inf})
        values.update({f"A{q}": math.inf for q in _QUANTILES})
        values["coverage"] = 0.0 if n_gt else math.nan
        return values
    real = arithmetic.real
    absolute = np.abs(signed).astype(real)
    for threshold in _BAD:
        values[f"bad {threshold:.1f}"] = (
            100.0 * int(np.count_nonzero(absolute > real(threshold))) / size
        )
    values["avgerr"] = float64_sum(absolute) / size
    squared = (signed * signed).astype(real)
    values["rms"] = arithmetic.root(float64_sum(squared) / size)
    ordered = np.sort(absolute)
    for q in _QUANTILES:
        values[f"A{q}"] = float(ordered[arithmetic.index(size, q)])
    values["coverage"] = 100.0 * (1.0 if size == n_gt else size / n_gt)
    return values


def eth3d_summary(frames: Sequence[FrameResult]) -> dict[str, dict[str, float]]:
    """Mean of every column over the frames."""
    return _weighted_mean(frames, [1.0] * len(frames))


# --------------------------------------------------------------------------- dispatch


@dataclass(frozen=True)
class FrameData:
    """The arrays one protocol frame needs (what a dataset tree gives)."""

    frame: str
    gt: np.ndarray
    gt_noc: np.ndarray | None = None
    nonocc_mask: np.ndarray | None = None
    obj_map: np.ndarray | None = None
    ndisp: float | None = None


def evaluate_frame(
    protocol: Protocol | str,
    data: FrameData,
    estimate: np.ndarray,
    arithmetic: Arithmetic | None = None,
) -> FrameResult:
    """One estimate on one frame under ``protocol``.

    By default the official arithmetic, with the exact twin in ``result.exact``; with an
    ``arithmetic``, only that one.
    """
    chosen = get_protocol(protocol) if isinstance(protocol, str) else protocol
    if arithmetic is None:
        result = evaluate_frame(chosen, data, estimate, OFFICIAL)
        result.exact = evaluate_frame(chosen, data, estimate, EXACT)
        return result
    if chosen.name == "middeval3":
        return middeval3_frame(
            data.frame, data.gt, estimate, data.nonocc_mask, data.ndisp, arithmetic
        )
    if chosen.name == "kitti2015":
        return kitti2015_frame(data.frame, data.gt, data.gt_noc, estimate, data.obj_map, arithmetic)
    if chosen.name == "kitti2012":
        return kitti2012_frame(data.frame, data.gt, data.gt_noc, estimate, arithmetic)
    return eth3d_frame(data.frame, data.gt, estimate, data.nonocc_mask, arithmetic)


def summarize_frames(
    protocol: Protocol | str,
    frames: Sequence[FrameResult],
    arithmetic: Arithmetic = OFFICIAL,
) -> dict[str, dict[str, float]]:
    """The benchmark's summary over ``frames`` (its own way of combining them)."""
    chosen = get_protocol(protocol) if isinstance(protocol, str) else protocol
    if not frames:
        raise ConfigurationError("no frame to summarise")
    if chosen.name == "middeval3":
        return middeval3_summary(frames)
    if chosen.name == "kitti2015":
        return kitti2015_summary(frames, arithmetic)
    if chosen.name == "kitti2012":
        return kitti2012_summary(frames, arithmetic)
    return eth3d_summary(frames)


def moved_digits(
    protocol: Protocol,
    official: Mapping[str, Mapping[str, float]],
    exact: Mapping[str, Mapping[str, float]],
) -> list[tuple[str, str, float, float]]:
    """``(region, column, official, exact)`` where the printed two decimals differ."""
    moved = []
    for region, values in official.items():
        for column in protocol.columns:
            have, want = values.get(column, math.nan), exact.get(region, {}).get(column, math.nan)
            if f"{have:.2f}" != f"{want:.2f}":
                moved.append((region, column, have, want))
    return moved


def objective_matrix(
    protocol: Protocol | str, results: Mapping[str, Sequence[FrameResult]]
) -> tuple[list[str], list[str], np.ndarray]:
    """Methods, objective names (``frame/region/column``) and values, for the A* Groups.

    The objectives are the protocol's lower-is-better columns in every region of every
    frame that all methods were scored on (a missing value counts as worst).
    """
    chosen = get_protocol(protocol) if isinstance(protocol, str) else protocol
    methods = list(results)
    names: list[str] = []
    columns: list[list[float]] = []
    by_frame = {m: {f.frame: f for f in results[m]} for m in methods}
    frames = list(dict.fromkeys(f.frame for m in methods for f in results[m]))
    for frame in frames:
        for region in chosen.regions:
            for column in chosen.objectives:
                values = []
                for method in methods:
                    found = by_frame[method].get(frame)
                    values.append(
                        found.values.get(region, {}).get(column, math.nan) if found else math.nan
                    )
                if all(math.isnan(v) for v in values):
                    continue
                names.append(f"{frame}/{region}/{column}")
                columns.append(values)
    matrix = np.array(columns, dtype=np.float64).T if columns else np.zeros((len(methods), 0))
    return methods, names, matrix


# ------------------------------------------------------------------------- streams (bags)


@dataclass(frozen=True)
class StreamPreset:
    """A protocol's measures for recorded streams, where frames are scored by summable sums.

    Bags carry no official region masks and the stream pipeline keeps exact arithmetic, so
    this is the benchmark's measures, thresholds and invalid-estimate handling over ``all``;
    ``differs`` says what is not the official tool's.
    """

    criteria: tuple[str, ...]
    measures: tuple[str, ...]
    missing: str
    differs: str

    def record(self) -> dict[str, object]:
        """Plain values for the run's configuration."""
        return {
            "criteria": list(self.criteria),
            "measures": list(self.measures),
            "missing": self.missing,
            "differs": self.differs,
        }


_EXACT = "exact arithmetic instead of the tool's float32 steps; no official region masks"
STREAM_PRESETS: dict[str, StreamPreset] = {
    "middeval3": StreamPreset(
        ("all",),
        ("bad_0.5", "bad_1", "bad_2", "bad_4", "mae", "rmse", "density"),
        "ignore",
        _EXACT + "; bad X over valid estimates (the SDK's 'bad'; its totals add 1 − density)",
    ),
    "kitti2015": StreamPreset(
        ("all",), ("d1", "density"), "interpolate", _EXACT + "; rows without estimate count 0"
    ),
    "kitti2012": StreamPreset(
        ("all",),
        ("bad_2", "bad_3", "bad_4", "bad_5", "mae", "density"),
        "interpolate",
        _EXACT + "; Out-k = bad_k, Avg = mae",
    ),
    "eth3d": StreamPreset(
        ("all",),
        ("bad_0.5", "bad_1", "bad_2", "bad_4", "mae", "rmse", "density"),
        "ignore",
        _EXACT + "; avgerr = mae, coverage = density",
    ),
}


def stream_preset(name: str) -> StreamPreset:
    """The stream preset of protocol ``name`` (a one-line error for unknown names)."""
    get_protocol(name)
    return STREAM_PRESETS[name]
