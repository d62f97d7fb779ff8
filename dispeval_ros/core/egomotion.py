"""Temporal noise without ground truth: the estimate at ``t`` moved into ``t + k`` by ego-motion.

Every pixel of the estimate ``d̂ₜ`` with a depth becomes a 3-D point of the left rectified
camera; the camera's rigid motion moves it into the camera at ``t + k``, where it lands at a
sub-pixel position with a predicted disparity. The residual is the estimate ``d̂ₜ₊ₖ`` there
(bilinear: exact on planes, whose disparity is affine in the image) minus the prediction, in
pixels, and the same in depth (metres). Pixels are masked, each reason counted on its own
(the first that applies, in this order): no estimate at ``t``; the point leaves the image
(behind the camera, or lands within ``border`` px of the edge); it is hidden at ``t + k``
(the z-buffer of the moved points, each written into its 2×2 bilinear support, holds at the
landing's nearest pixel a disparity larger by more than ``occlusion_tolerance`` px); the
estimate at ``t + k`` has a hole in the support; it is near a depth edge (a 4-neighbour jump
larger than ``edge_gap`` dilated by ``edge_width``) in either map; the left image at ``t`` and
the left image at ``t + k`` at the landing differ by more than ``photometric_threshold`` grey
levels (the point moved, or is not what the motion assumes; such a point hides nothing).

It measures noise, not bias. A constant disparity offset ``b`` is a ``doffs`` error: under a
motion along the optical axis it does not cancel (``Z`` changes, so does the disparity's
sensitivity to it). By default the offset that explains the pair best (least absolute
residuals of a sparse grid, both maps shifted by ``−b``: :func:`_fit_offset`) is removed and
reported; under it a method with a constant bias scores what it scores without the bias. The
offset is weakly observable, so its fitted value is noisy: not a bias estimate. Without
``fit_offset`` a constant offset cancels exactly only for a static camera and for motions that
keep every depth (rotation about the optical axis; translation parallel to the image over
fronto-parallel surfaces).

For a static camera (no motion) :class:`FlickerWindow` gives flicker: the per-pixel sample
spread (``ddof = 1``) of the estimate over a window of frames. Both produce
:class:`TemporalSums`: per-criterion sums, so pooled sums over a sequence are exact.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numba import types
from numba.typed import List

from dispeval_ros.core import criteria as crit
from dispeval_ros.core.camera import Camera
from dispeval_ros.core.evaluator import as_disparity
from dispeval_ros.core.gtfree import grey8
from dispeval_ros.core.kernels import motion as km
from dispeval_ros.core.kernels import motion_fit as kf
from dispeval_ros.core.measures import DEFAULT_BAD_THRESHOLDS
from dispeval_ros.core.transforms import check_rotation, invert_rigid
from dispeval_ros.errors import (
    CalibrationError,
    ConfigurationError,
    InputError,
    ShapeMismatchError,
)

STATUS_NAMES = ("residual", "missing", "border", "hidden", "missing_target", "edge", "moving")
"""What happened to a pixel, by status code: counted, or the mask that removed it."""
BASE_COLUMNS = (
    "n",
    *(f"n_{name}" for name in STATUS_NAMES),
    "sum_abs",
    "sum",
    "sum_sq",
    "sum_abs_z",
    "sum_sq_z",
)
"""The sums' columns before one ``bad`` count per threshold (``|r| > threshold``)."""


@dataclass(frozen=True)
class PinholeCamera:
    """The left rectified camera: :class:`Camera` (``f``, ``B``, ``doffs``) and principal point."""

    camera: Camera
    cx: float
    cy: float

    def __post_init__(self) -> None:
        for name in ("cx", "cy"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise CalibrationError(f"camera {name} must be a finite number, got {value!r}")

    def geometry(self) -> np.ndarray:
        """``(f, cx, cy, f·B, doffs)`` as the kernels read it."""
        c = self.camera
        return np.array([c.f, self.cx, self.cy, c.fb, c.doffs], dtype=np.float64)


@dataclass(frozen=True)
class EgoMotionOptions:
    """Masks, thresholds and the offset fit (see the module).

    ``edge_gap`` and ``edge_width`` apply where edge masks are made: :func:`prepare_frame`
    and :class:`FlickerWindow`; a residual uses the masks of the frames it is given.
    """

    border: float = 0.0
    occlusion_tolerance: float = 2.0
    edge_gap: float = 2.0
    edge_width: int = 3
    photometric_threshold: float = 16.0
    thresholds: tuple[float, ...] = DEFAULT_BAD_THRESHOLDS
    fit_offset: bool = True

    def __post_init__(self) -> None:
        for name in ("border", "occlusion_tolerance", "edge_gap", "photometric_threshold"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ConfigurationError(f"ego-motion {name} must be a number ≥ 0, got {value!r}")
        if not isinstance(self.edge_width, int) or self.edge_width < 1:
            raise ConfigurationError(
                f"ego-motion edge_width must be a whole number of px ≥ 1, got {self.edge_width!r}"
            )
        if not all(t >= 0 for t in self.thresholds):
            raise ConfigurationError(f"ego-motion thresholds must be ≥ 0, got {self.thresholds!r}")


@dataclass(frozen=True)
class MotionFrame:
    """One frame prepared once (used as the source of one pair and the target of another).

    ``disparity`` is float32 with NaN where the estimate is missing; ``edges`` marks pixels
    near a depth edge; ``image`` is the left grey image (0×0 when not given).
    """

    disparity: np.ndarray
    edges: np.ndarray
    image: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        """Image size (rows, columns)."""
        return (int(self.disparity.shape[0]), int(self.disparity.shape[1]))


_NO_IMAGE = np.zeros((0, 0), dtype=np.uint8)


def prepare_frame(
    estimate: object,
    image: object | None = None,
    *,
    valid_range: tuple[float, float] | None = None,
    options: EgoMotionOptions | None = None,
    what: str = "the estimate",
) -> MotionFrame:
    """Check one estimate (and its left image) and find its depth edges.

    Missing: not finite, or ``≤ 0`` (``valid_range``: outside ``[lo, hi]`` instead, for
    DisparityImages whose valid values may be 0 or negative).
    """
    chosen = options or EgoMotionOptions()
    disparity = as_disparity(estimate, what)
    if min(disparity.shape) < 2:
        raise InputError(f"{what} is {crit.size_text(disparity.shape)}: at least 2×2 is needed")
    if valid_range is None:
        valid = np.empty(disparity.shape, np.bool_)
        checked = np.empty_like(disparity)
        km.positive_disparity(disparity, checked, valid)
        disparity = checked
    else:  # numpy's comparison (NEP 50 decides the precision of the bounds)
        with np.errstate(invalid="ignore"):
            valid = (disparity >= valid_range[0]) & (disparity <= valid_range[1])
        disparity = np.where(valid, disparity, np.float32(np.nan))
    edges = crit.discontinuities(disparity, valid, chosen.edge_gap, chosen.edge_width)
    grey = _NO_IMAGE
    if image is not None:
        grey = grey8(image, f"the left image of {what}")
        if grey.shape != disparity.shape:
            raise ShapeMismatchError(
                f"the left image is {crit.size_text(grey.shape)} but {what} is "
                f"{crit.size_text(disparity.shape)}"
            )
    return MotionFrame(disparity, np.ascontiguousarray(edges), grey)


def rigid_motion(motion: object, what: str = "the camera motion") -> np.ndarray:
    """A 4×4 rigid transform (float64), or an :class:`InputError` saying what is wrong."""
    try:
        matrix = np.asarray(motion, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise InputError(f"{what} is not a 4×4 matrix: {error}") from None
    if matrix.shape != (4, 4):
        raise InputError(f"{what} must be a 4×4 matrix, got shape {matrix.shape}")
    if not np.isfinite(matrix).all():
        raise InputError(f"{what} holds non-finite values")
    if not np.allclose(matrix[3], [0, 0, 0, 1], atol=1e-9):
        raise InputError(f"{what}: the last row must be 0 0 0 1, got {matrix[3].tolist()}")
    try:
        check_rotation(matrix[:3, :3], f"{what}: the 3×3 rotation part")
    except CalibrationError as error:
        raise InputError(f"{error} (the motion must be rigid)") from None
    return matrix


def camera_motion(pose_t: object, pose_tk: object) -> np.ndarray:
    """The motion from two camera poses in one fixed frame (``odom ← camera`` at each stamp).

    Returns the pose of the camera at ``t + k`` in the camera frame at ``t`` (what
    :func:`egomotion_residual` takes): ``pose_t⁻¹ · pose_tk``.
    """
    first = rigid_motion(pose_t, "the camera pose at t")
    second = rigid_motion(pose_tk, "the camera pose at t + k")
    return invert_rigid(first) @ second


@dataclass(frozen=True)
class TemporalSums:
    """Per-criterion sums of a temporal measure: pooled by ``+``, exact over a sequence.

    ``sums[i]`` holds criterion ``criteria[i]``'s :data:`BASE_COLUMNS` then one count per
    threshold. ``offsets`` are the offsets removed, one per pair (px; none for flicker);
    ``measure`` is ``egomotion`` or ``flicker``.
    """

    measure: str
    criteria: tuple[str, ...]
    thresholds: tuple[float, ...]
    sums: np.ndarray
    offsets: tuple[float, ...] = ()
    maps: tuple[np.ndarray, ...] = field(default=(), compare=False, repr=False)
    """Per-pixel status, residual (px) and depth residual (m) when asked for; not pooled."""

    @property
    def columns(self) -> tuple[str, ...]:
        """Names of the sums' columns."""
        return (*BASE_COLUMNS, *(f"bad_{t:g}" for t in self.thresholds))

    def __add__(self, other: TemporalSums) -> TemporalSums:
        if (other.measure, other.criteria, other.thresholds) != (
            self.measure,
            self.criteria,
            self.thresholds,
        ):
            raise ConfigurationError(
                f"cannot pool {other.measure} sums over {', '.join(other.criteria)} with "
                f"{self.measure} sums over {', '.join(self.criteria)} (or other thresholds)"
            )
        return TemporalSums(
            self.measure,
            self.criteria,
            self.thresholds,
            self.sums + other.sums,
            self.offsets + other.offsets,
        )

    @classmethod
    def of_pair(
        cls, criteria: Sequence[str], thresholds: Sequence[float], sums: object, offset: float
    ) -> TemporalSums:
        """One pair's ego-motion sums from the parts they are stored as (a row, a status's keys).

        Raises ValueError without a criterion or when the sums are not criteria × (base
        columns + thresholds).
        """
        names, levels = tuple(criteria), tuple(float(t) for t in thresholds)
        values = np.array(sums, dtype=np.float64)
        width = len(BASE_COLUMNS) + len(levels)
        if not names or values.size != len(names) * width:
            raise ValueError(f"{len(names)} criteria, {values.size} sums of {width} columns")
        return cls("egomotion", names, levels, values.reshape(len(names), width), (offset,))

    def column(self, criterion: str, name: str) -> float:
        """One sum of one criterion."""
        return float(self.sums[self.criteria.index(criterion), self.columns.index(name)])

    def summary(self, criterion: str) -> dict[str, float]:
        """Counts and the derived values of one criterion (NaN where nothing was counted).

        ``mean_abs``, ``rms``, ``mean`` (signed; flicker: the mean spread) in px,
        ``mean_abs_z`` and ``rms_z`` in metres, ``bad_X`` in % of the counted pixels.
        """
        row = dict(zip(self.columns, self.sums[self.criteria.index(criterion)], strict=True))
        n = row["n_residual"]
        out = {name: float(row[name]) for name in BASE_COLUMNS[: 1 + len(STATUS_NAMES)]}

        def per(value: float) -> float:
            return value / n if n else math.nan

        out["mean_abs"] = per(row["sum_abs"])
        out["mean"] = per(row["sum"])
        out["rms"] = math.sqrt(per(row["sum_sq"])) if n else math.nan
        out["mean_abs_z"] = per(row["sum_abs_z"])
        out["rms_z"] = math.sqrt(per(row["sum_sq_z"])) if n else math.nan
        for t in self.thresholds:
            out[f"bad_{t:g}"] = 100.0 * per(row[f"bad_{t:g}"])
        return out


_BUFFERS = threading.local()


def _buffers(shape: tuple[int, int]) -> tuple[np.ndarray, ...]:
    """This thread's z-buffer, moving marks and maps for one size (written in full by each use)."""
    held = getattr(_BUFFERS, "held", None)
    if held is None or held[0].shape != shape:
        held = (
            np.empty(shape, np.float32),
            np.empty(shape, np.bool_),
            np.empty(shape, np.int8),
            np.empty(shape, np.float32),
            np.empty(shape, np.float32),
        )
        _BUFFERS.held = held
    return held


def _row_maps(width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Status and residual maps of one row, for a kernel that need not keep the whole maps."""
    return (np.empty((1, width), np.int8), *np.empty((2, 1, width), np.float32))


def _cells(
    partition: crit.Partition | None, shape: tuple[int, int], rows: int | None = None
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Cells, membership and criterion names (``all``: every pixel, without a partition).

    ``rows=1``: without a partition, one row of cells that the kernel uses for every row.
    """
    if partition is None:
        return np.zeros((rows or shape[0], shape[1]), np.int32), np.ones((1, 1), bool), ("all",)
    if partition.shape != shape:
        raise ShapeMismatchError(
            f"the criteria are {crit.size_text(partition.shape)} but the estimates are "
            f"{crit.size_text(shape)}"
        )
    cells = np.ascontiguousarray(partition.cells, dtype=np.int32)
    return cells, partition.membership, partition.criteria


def egomotion_residual(
    source: MotionFrame,
    target: MotionFrame,
    motion: object,
    camera: PinholeCamera,
    partition: crit.Partition | None = None,
    options: EgoMotionOptions | None = None,
    *,
    keep_maps: bool = False,
) -> TemporalSums:
    """The ego-motion residual of one pair (``source`` at ``t``, ``target`` at ``t + k``).

    ``motion``: the pose of the left camera at ``t + k`` in the left camera frame at ``t``
    (4×4, tf2's ``lookup(camera@t, camera@t+k)``, :func:`camera_motion`); a drive forward by
    1 m is a translation ``(0, 0, 1)``. ``partition``: criteria of the source frame (pixels
    not evaluated: cells < 0), default ``all``. ``keep_maps``: keep copies of the per-pixel
    status, residual and depth residual.
    """
    chosen = options or EgoMotionOptions()
    shape = _same_size(source, target)
    rt = np.ascontiguousarray(invert_rigid(rigid_motion(motion))[:3])
    geo = camera.geometry()
    cells, membership, names = _cells(partition, shape, rows=1)
    zbuffer, moving, status, residual, residual_z = _buffers(shape)
    # one tuple type (numba compiles one signature); maps not kept: one row, rewritten per row
    maps = (status, residual, residual_z) if keep_maps else _row_maps(shape[1])
    scratch = km.row_buffers(shape[1])
    limits = np.array([chosen.border, chosen.occlusion_tolerance], np.float64)
    thresholds = np.asarray(chosen.thresholds, dtype=np.float64)
    images = (source.image, target.image)
    if images[0].size == 0 or images[1].size == 0:
        images = (_NO_IMAGE, _NO_IMAGE)
    src = (source.disparity, source.edges)
    tgt = (target.disparity, target.edges)
    offset = _fit_offset(source, tgt, images, rt, geo, chosen) if chosen.fit_offset else 0.0
    sums = np.zeros((membership.shape[1], len(BASE_COLUMNS) + thresholds.size), np.float64)
    threshold = chosen.photometric_threshold
    km.motion_splat(source.disparity, images, rt, geo, offset, threshold, zbuffer, moving, scratch)
    km.motion_classify(
        src, tgt, rt, geo, offset, limits, zbuffer, moving, cells, thresholds, sums, maps, scratch
    )
    kept = tuple(m.copy() for m in maps) if keep_maps else ()
    return TemporalSums(
        "egomotion",
        names,
        tuple(float(t) for t in chosen.thresholds),
        membership.astype(np.float64) @ sums,
        (offset,),
        kept,
    )


FIT_STRIDE = 6
"""The offset is fitted on every 6th pixel of every 6th row: one constant needs few pixels."""
FIT_ITERATIONS = 3
FIT_TOLERANCE = 1e-6
"""The fit stops when the offset changes by less than this (px)."""
FIT_MINIMUM = 16
FIT_FLOOR = 0.01
"""The inlier bound of the fit never shrinks below this (px): exact estimates have r ≈ 1e-6."""
OBSERVABLE = 1e-3
"""The offset is left at 0 when the mean ``|dr/db|`` is below this: the motion (a static
camera, a sideways one) hardly changes the depths, and a constant offset then cancels."""


def _fit_offset(
    source: MotionFrame,
    target: tuple[np.ndarray, np.ndarray],
    images: tuple[np.ndarray, np.ndarray],
    rt: np.ndarray,
    geo: np.ndarray,
    options: EgoMotionOptions,
) -> float:
    """The disparity offset that minimises the sum of absolute residuals.

    On a sparse grid of pixels (:data:`FIT_STRIDE`) passing the masks that need no z-buffer;
    each step solves the linearised problem exactly (the weighted median of the inliers'
    steps, :func:`~.kernels.motion_fit.l1_candidates`). The absolute value lets moving pixels the
    photometric check missed and hidden points pass without pulling the offset; squares would
    also trade noise against it (the offset changes how much the depth amplifies the noise).
    Under a constant bias every static pixel's residual is 0 at the bias: the fit finds it
    exactly.
    """
    samples = kf.fit_samples(source.disparity, source.edges, FIT_STRIDE)
    out = (np.empty(samples.shape[0], np.float64), np.empty(samples.shape[0], np.float64))
    candidates = (np.empty(samples.shape[0], np.float64), np.empty(samples.shape[0], np.float64))
    offset = 0.0
    for _ in range(FIT_ITERATIONS):
        written = kf.offset_residuals(
            source.disparity,
            target,
            images,
            samples,
            rt,
            geo,
            offset,
            options.photometric_threshold,
            out,
        )
        if written < FIT_MINIMUM:
            break
        kept, total = kf.l1_candidates(out[0][:written], out[1][:written], FIT_FLOOR, candidates)
        steps = candidates[0][:kept]
        step, observability = kf.weighted_median(steps, candidates[1], np.argsort(steps), total)
        if not observability >= OBSERVABLE:
            break
        offset += step
        if abs(step) < FIT_TOLERANCE:
            break
    return float(offset)


def _same_size(*frames: MotionFrame) -> tuple[int, int]:
    shape = frames[0].shape
    for number, frame in enumerate(frames[1:], start=2):
        if frame.shape != shape:
            raise ShapeMismatchError(
                f"estimate {number} is {crit.size_text(frame.shape)} but the first is "
                f"{crit.size_text(shape)}"
            )
    return shape


class FlickerWindow:
    """Flicker of a static camera: frames added one by one, the spread per pixel at the end.

    A pixel counts when it has an estimate in every frame, is near no depth edge of the
    window's mean map (a single frame's edges would follow its noise and mask the noisiest
    pixels) and (with images) its intensity range over the window is within the photometric
    threshold. The window keeps its frames (references, no copies) until :meth:`sums`.
    """

    def __init__(self, camera: Camera, options: EgoMotionOptions | None = None) -> None:
        self.camera = camera
        self.options = options or EgoMotionOptions()
        self._frames: list[MotionFrame] = []

    @property
    def frames(self) -> int:
        """Frames added so far."""
        return len(self._frames)

    def add(self, frame: MotionFrame) -> None:
        """Add the next frame of the window (same size; with an image if the first had one)."""
        if self._frames:
            first = self._frames[0]
            if frame.shape != first.shape:
                raise ShapeMismatchError(
                    f"frame {self.frames + 1} of the flicker window is "
                    f"{crit.size_text(frame.shape)} but the first is {crit.size_text(first.shape)}"
                )
            if (frame.image.size > 0) != (first.image.size > 0):
                raise InputError(
                    f"frame {self.frames + 1} of the flicker window "
                    f"{'has a' if frame.image.size else 'has no'} left image, unlike the first"
                )
        self._frames.append(frame)

    def sums(
        self, partition: crit.Partition | None = None, *, keep_maps: bool = False
    ) -> TemporalSums:
        """The window's sums per criterion (at least two frames are needed)."""
        if self.frames < 2:
            raise InputError(f"flicker needs at least 2 frames in a window, got {self.frames}")
        shape = self._frames[0].shape
        cells, membership, names = _cells(partition, shape, rows=1)
        thresholds = np.asarray(self.options.thresholds, dtype=np.float64)
        sums = np.zeros((membership.shape[1], len(BASE_COLUMNS) + thresholds.size), np.float64)
        zbuffer, _, status, residual, residual_z = _buffers(shape)
        maps = (status, residual, residual_z)
        mean = zbuffer  # this thread's float32 scratch of the image size
        disparities = List([frame.disparity for frame in self._frames])
        images = List([frame.image for frame in self._frames if frame.image.size])
        if not images:
            images = List.empty_list(types.uint8[:, ::1])
        km.flicker_spread(
            disparities,
            images,
            self.camera.fb,
            self.camera.doffs,
            self.options.photometric_threshold,
            mean,
            maps,
        )
        edges = crit.discontinuities(
            mean, np.isfinite(mean), self.options.edge_gap, self.options.edge_width
        )
        km.flicker_sums(np.ascontiguousarray(edges), cells, thresholds, sums, maps)
        return TemporalSums(
            "flicker",
            names,
            tuple(float(t) for t in self.options.thresholds),
            membership.astype(np.float64) @ sums,
            (),
            _counted_maps(maps) if keep_maps else (),
        )


def _counted_maps(maps: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[np.ndarray, ...]:
    """Copies of the status and spread maps, the spreads NaN where a pixel was not counted."""
    status, spread, spread_z = maps
    counted = status == km.COUNTED
    nan = np.float32(np.nan)
    return status.copy(), np.where(counted, spread, nan), np.where(counted, spread_z, nan)


def flicker(
    frames: Sequence[MotionFrame],
    camera: Camera,
    partition: crit.Partition | None = None,
    options: EgoMotionOptions | None = None,
) -> TemporalSums:
    """Flicker of one window of frames of a static camera (see :class:`FlickerWindow`)."""
    window = FlickerWindow(camera, options)
    for frame in frames:
        window.add(frame)
    return window.sums(partition)
