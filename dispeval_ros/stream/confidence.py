"""Each method's confidence sums added up over the frames of a stream or of a unit of work.

Frames' :class:`~dispeval_ros.core.confidence.ConfidenceSums` are summed as they are scored
(no frame's tables are kept), so a unit stores one row per method and a sequence's curves are
its rows added: exactly the curves of all its pixels at once.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from dispeval_ros.core.confidence import ConfidenceSums
from dispeval_ros.core.records import PooledConfidence
from dispeval_ros.stream.results import FrameResult


@dataclass
class _Running:
    start: int
    stamp: int
    frames: int
    sums: ConfidenceSums


class ConfidencePool:
    """The running sums per method of ``sequence``; ``presets``: each method's, as configured."""

    def __init__(self, sequence: str, presets: Mapping[str, str]) -> None:
        self.sequence = sequence
        self.presets = dict(presets)
        self._running: dict[str, _Running] = {}

    def add(self, frame: FrameResult) -> None:
        """Add a scored frame's confidence sums (frames in any order: sums commute)."""
        for method, sums in frame.confidence.items():
            running = self._running.get(method)
            if running is None:
                self._running[method] = _Running(frame.stamp, frame.stamp, 1, sums)
                continue
            running.start = min(running.start, frame.stamp)
            running.stamp = max(running.stamp, frame.stamp)
            running.frames += 1
            running.sums = running.sums + sums

    def __bool__(self) -> bool:
        return bool(self._running)

    def records(self, clear: bool = True) -> list[PooledConfidence]:
        """The pooled sums as records to store (one per method); ``clear``: start again."""
        records = [
            PooledConfidence(
                self.sequence, r.start, r.stamp, method, r.frames, self.presets[method], r.sums
            )
            for method, r in self._running.items()
        ]
        if clear:
            self._running = {}
        return records
