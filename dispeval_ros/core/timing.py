"""Latency and rate of one method over one sequence: delays, frame rate, missed frames, jitter.

A method's *delay* at a frame is its estimate's arrival (a bag's log time, the receipt time
live) minus its header stamp. Rate, missed frames and jitter follow NVIDIA ros2_benchmark
(``ros2_benchmark/ros2_benchmark/basic_performance_calculator.py``, NVIDIA-ISAAC-ROS/
ros2_benchmark), with the arrivals as its *end timestamps* and the ground-truth frames as the
frames *sent*:

- jitter: ``|diff(diff(arrivals))|`` in arrival order (ms), its mean, max and standard
  deviation; defined from 3 arrivals;
- missed frames: frames sent minus frames received, here the ground-truth frames the method
  never delivered (the join's *dropped* count);
- their ``MEAN_FRAME_RATE`` is ``received / (last − first arrival)``: n frames over n − 1
  intervals. Ours, ``fps``, is ``(n − 1) / (last − first arrival)`` (10 fps for frames every
  100 ms); the ros2_benchmark export (:func:`benchmark_keys`) keeps theirs.

Per window: arrivals counted in consecutive windows of :data:`WINDOW_NS` from the first one,
complete windows only (the last, cut short, is left out); ``fps_min`` is the slowest window.
Quantiles are numpy's default (linear interpolation between order statistics).

A timing measure is one value per method and sequence, not per criterion: as an objective
(``--objective-measures sze bmpre latency_p95``) it is one column per sequence
(``latency_p95 @sequence``), whatever ``--objectives`` says, beside the criteria's columns;
higher-is-better ones (frame rates) are negated so that every objective is minimised.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "TIMING_MEASURES",
    "WINDOW_NS",
    "Timing",
    "TimingMeasure",
    "benchmark_keys",
    "is_timing_measure",
    "timing_of",
]

WINDOW_NS = 1_000_000_000
"""The window of the per-window frame rate (arrival time)."""
WINDOW_LIST_LIMIT = 100_000
"""At most this many windows' rates are listed (more than a day of 1 s windows)."""
_MS = 1e6


@dataclass(frozen=True)
class TimingMeasure:
    """A timing measure: its unit, its direction and what it is (for help and tables)."""

    name: str
    unit: str
    higher_is_better: bool
    text: str


TIMING_MEASURES = {
    m.name: m
    for m in (
        TimingMeasure("latency_median", "ms", False, "median delay (arrival − header stamp)"),
        TimingMeasure("latency_p95", "ms", False, "95th percentile of the delay"),
        TimingMeasure("latency_max", "ms", False, "largest delay"),
        TimingMeasure("latency_mean", "ms", False, "mean delay"),
        TimingMeasure("fps", "Hz", True, "frames per second between first and last arrival"),
        TimingMeasure("fps_min", "Hz", True, "frame rate of the slowest complete window"),
        TimingMeasure("missed", "frames", False, "ground-truth frames never delivered"),
        TimingMeasure("jitter_mean", "ms", False, "mean |change of the arrival interval|"),
        TimingMeasure("jitter_max", "ms", False, "largest |change of the arrival interval|"),
    )
}
"""Every timing measure, defined once: the objectives, the tables and the JSON read it."""


def is_timing_measure(name: str) -> bool:
    """Whether ``name`` is a timing measure (not a per-criterion score)."""
    return name in TIMING_MEASURES


@dataclass(frozen=True)
class Timing:
    """The timing of one method over one sequence (times in ms, rates in Hz; NaN: undefined)."""

    frames: int
    missed: int
    latency_median: float
    latency_p95: float
    latency_max: float
    latency_mean: float
    latency_min: float
    first_latency: float
    last_latency: float
    span: float
    """Last minus first arrival (ms): ros2_benchmark's RECEIVED_DURATION."""
    fps: float
    fps_min: float
    windows: int
    """Complete windows of :data:`WINDOW_NS` between the first and last arrival."""
    window_fps: tuple[float, ...]
    """Each complete window's frame rate (none listed beyond :data:`WINDOW_LIST_LIMIT`)."""
    jitter_mean: float
    jitter_max: float
    jitter_min: float
    jitter_std: float

    def value(self, name: str) -> float:
        """The value of timing measure ``name``."""
        if name not in TIMING_MEASURES:
            raise KeyError(name)
        return float(getattr(self, name))

    def to_dict(self) -> dict[str, object]:
        """JSON-ready (NaN left for the JSON writer to turn into null), window rates included."""
        fields = {name: getattr(self, name) for name in self.__dataclass_fields__}
        fields["window_fps"] = list(self.window_fps)
        fields["window_s"] = WINDOW_NS / 1e9
        return fields


_FLOAT_FIELDS = tuple(
    name
    for name in Timing.__dataclass_fields__
    if name not in ("frames", "missed", "windows", "window_fps")
)


def timing_of(
    stamps: Sequence[int], arrivals: Sequence[int], missed: int, window_ns: int = WINDOW_NS
) -> Timing:
    """The timing of estimates with header ``stamps`` that arrived at ``arrivals`` (ns).

    ``missed``: the ground-truth frames the method never delivered. Arrivals are taken in
    arrival order (equal arrivals in the order given).
    """
    sent = np.asarray(stamps, dtype=np.int64)
    arrived = np.asarray(arrivals, dtype=np.int64)
    order = np.argsort(arrived, kind="stable")
    sent, arrived = sent[order], arrived[order]
    nan = math.nan
    if not len(arrived):
        undefined = dict.fromkeys(_FLOAT_FIELDS, nan)
        return Timing(frames=0, missed=missed, windows=0, window_fps=(), **undefined)
    delays = (arrived - sent).astype(np.float64) / _MS
    span = int(arrived[-1] - arrived[0])
    fps = (len(arrived) - 1) / (span / 1e9) if span > 0 else nan
    windows, slowest, window_fps = _window_rates(arrived, window_ns)
    jitter = np.abs(np.diff(np.diff(arrived))).astype(np.float64) / _MS
    has_jitter = len(jitter) > 0
    return Timing(
        frames=len(arrived),
        missed=missed,
        latency_median=float(np.median(delays)),
        latency_p95=float(np.percentile(delays, 95)),
        latency_max=float(delays.max()),
        latency_mean=float(delays.mean()),
        latency_min=float(delays.min()),
        first_latency=float(delays[0]),
        last_latency=float(delays[-1]),
        span=span / _MS,
        fps=fps,
        fps_min=slowest,
        windows=windows,
        window_fps=window_fps,
        jitter_mean=float(jitter.mean()) if has_jitter else nan,
        jitter_max=float(jitter.max()) if has_jitter else nan,
        jitter_min=float(jitter.min()) if has_jitter else nan,
        jitter_std=float(jitter.std()) if has_jitter else nan,
    )


def _window_rates(arrived: np.ndarray, window_ns: int) -> tuple[int, float, tuple[float, ...]]:
    """Complete windows of ``window_ns`` from the first arrival, the slowest one's rate, each's.

    Each window's rate up to :data:`WINDOW_LIST_LIMIT` windows, else none: a clock that
    jumped years would list millions of empty windows.
    """
    complete = int(arrived[-1] - arrived[0]) // window_ns
    if complete == 0:
        return 0, math.nan, ()
    index = (arrived - arrived[0]) // window_ns
    occupied, counts = np.unique(index[index < complete], return_counts=True)
    per_second = window_ns / 1e9
    slowest = 0.0 if len(occupied) < complete else float(counts.min()) / per_second
    if complete > WINDOW_LIST_LIMIT:
        return complete, slowest, ()
    full = np.zeros(complete, dtype=np.int64)
    full[occupied] = counts
    return complete, slowest, tuple(float(count) / per_second for count in full)


def benchmark_keys(timing: Timing) -> dict[str, float | int]:
    """The timing in ros2_benchmark's result-JSON keys (``BasicPerformanceMetrics.*``, ms).

    ``MEAN_FRAME_RATE`` is theirs (received frames over the received duration), the frames
    sent are the ground-truth frames (delivered + missed); the latency keys are end-to-end
    (header stamp to arrival), as their ``message_key_match`` computes them.
    """
    received = timing.frames
    values: dict[str, float | int] = {
        "RECEIVED_DURATION": timing.span,
        "MEAN_FRAME_RATE": received / (timing.span / 1e3) if timing.span > 0 else math.nan,
        "NUM_MISSED_FRAMES": timing.missed,
        "NUM_FRAMES_SENT": received + timing.missed,
        "FIRST_INPUT_LATENCY": timing.first_latency,
        "LAST_INPUT_LATENCY": timing.last_latency,
        "MAX_LATENCY": timing.latency_max,
        "MIN_LATENCY": timing.latency_min,
        "MEAN_LATENCY": timing.latency_mean,
        "MAX_JITTER": timing.jitter_max,
        "MIN_JITTER": timing.jitter_min,
        "MEAN_JITTER": timing.jitter_mean,
        "STD_DEV_JITTER": timing.jitter_std,
    }
    return {f"BasicPerformanceMetrics.{key}": value for key, value in values.items()}
