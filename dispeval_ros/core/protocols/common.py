"""What every benchmark protocol shares: the preset record, frame results and arithmetic.

The project's own measures (:mod:`dispeval_ros.core.measures`) keep exact arithmetic; a
protocol does every step the official tool does in ``float`` (float32) in float32 too, because
that is what the leaderboard shows. :class:`Arithmetic` holds those steps once, so each
protocol module runs in both the official and the exact arithmetic and the report can say
where float32 moves a printed digit.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from dispeval_ros.errors import ShapeMismatchError

F32 = np.float32

_QUANTILES = (50, 90, 95, 99)
_BAD = (0.5, 1.0, 2.0, 4.0)
_BAD_COLUMNS = tuple(f"bad {t:.1f}" for t in _BAD)
_QUANTILE_COLUMNS = tuple(f"A{q}" for q in _QUANTILES)


def _error_columns(average: str) -> tuple[str, ...]:
    """The Middlebury-style error columns (MiddEval3 and ETH3D name the mean differently)."""
    return (*_BAD_COLUMNS, average, "rms", *_QUANTILE_COLUMNS)


def config_sha256(record: Mapping[str, object]) -> str:
    """sha256 of a configuration record as canonical JSON (sorted keys, no spaces)."""
    text = json.dumps(record, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


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


@dataclass(frozen=True)
class FrameData:
    """The arrays one protocol frame needs (what a dataset tree gives)."""

    frame: str
    gt: np.ndarray
    gt_noc: np.ndarray | None = None
    nonocc_mask: np.ndarray | None = None
    obj_map: np.ndarray | None = None
    ndisp: float | None = None


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


#: How a protocol scores one frame: the dataset's arrays, one estimate, one arithmetic.
FrameFunction = Callable[[FrameData, np.ndarray, Arithmetic], FrameResult]
#: A summary table, region → column → value.
SummaryTable = dict[str, dict[str, float]]
#: How a protocol combines its frames into the summary table.
SummaryFunction = Callable[[Sequence[FrameResult], Arithmetic], SummaryTable]


def double_summary(combine: Callable[[Sequence[FrameResult]], SummaryTable]) -> SummaryFunction:
    """A summary the tool takes in double over stored frame values: one for both arithmetics."""
    return lambda frames, arithmetic: combine(frames)


#: The result encodings the official tools read, and how each marks "no estimate".
RESULT_ENCODINGS = {
    "png16": "1-channel 16-bit PNG (disparity × 256, 0 = no estimate)",
    "pfm": "PFM (INF = no estimate)",
}


@dataclass(frozen=True)
class ResultLayout:
    """Where a benchmark's tool finds a method's result for a frame, and in which encoding.

    The one definition read by the lookup, its error message and the README. ``folder``: paths
    under a results folder (``--est NAME=RESULTS``); ``scene``: paths in the frame's own folder
    (``--est NAME``; empty where the results never live in the dataset tree). ``{frame}`` is
    the frame's name (its scene folder, or KITTI's ``NNNNNN_10``), ``{method}`` the method's.
    """

    folder: tuple[str, ...]
    scene: tuple[str, ...]
    encoding: str

    def paths(self, in_folder: bool, frame: str, method: str) -> list[str]:
        """The relative paths of ``frame``'s result, in the listed order."""
        templates = self.folder if in_folder else self.scene
        return [t.format(frame=frame, method=method) for t in templates]

    def encoding_text(self) -> str:
        """The encoding as the official tool wants it (for refusals and the README)."""
        return RESULT_ENCODINGS[self.encoding]

    def describe(self) -> str:
        """Every accepted layout and the encoding in one line (README 'Reproduce a benchmark')."""
        folder = ", ".join(f"`RESULTS/{p}`" for p in self.paths(True, "<frame>", "NAME"))
        scene = ", ".join(f"`<frame>/{p}`" for p in self.paths(False, "<frame>", "NAME"))
        where = f"`--est NAME=RESULTS`: {folder}"
        if scene:
            where = f"`--est NAME`: {scene} in the dataset tree; {where}"
        return f"{where}; {self.encoding_text()}"


@dataclass(frozen=True)
class Protocol:
    """One benchmark's evaluation preset.

    ``regions`` and ``columns`` are the official names in the official order; ``percent``
    lists the columns shown as percentages; ``objectives`` are the lower-is-better columns the
    A* Groups compare; ``summary`` says how frames are combined; ``float32`` where the official
    tool's float32 arithmetic is reproduced. ``frame_function`` and ``summary_function`` are
    the benchmark's own arithmetic, so callers dispatch through the preset, never on its name;
    ``results`` where its tool finds a method's results (not in :meth:`record`: it moves no
    number).
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
    frame_function: FrameFunction = field(repr=False, compare=False)
    summary_function: SummaryFunction = field(repr=False, compare=False)
    results: ResultLayout = field(repr=False, compare=False)
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
