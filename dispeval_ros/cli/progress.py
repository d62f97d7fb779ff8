"""A dependency-free progress line on stderr for long runs (silent when not wanted)."""

from __future__ import annotations

import sys
import time
from typing import TextIO


class Progress:
    """``[#####.....] 12/40 slices  345 frames  210.3 frames/s``, redrawn in place on a terminal.

    A slice is the unit of work: a few seconds of one recording, scored and stored together.
    With ``unit="frames"`` (work counted in frames, as ``make-bag`` writes them) the line reads
    ``[#####.....] 12/40 frames  3.3 frames/s``.

    When stderr is not a terminal (CI logs), it prints a plain line about every 10 %.
    """

    def __init__(
        self,
        label: str,
        enabled: bool = True,
        stream: TextIO | None = None,
        unit: str = "slices",
    ) -> None:
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.unit = unit
        self.started = time.perf_counter()
        self._last_decile = -1
        self._tty = self.stream.isatty()

    def update(self, done: int, total: int, frames: int) -> None:
        """Show ``done`` of ``total`` units of work and the frame rate so far."""
        if not self.enabled or total <= 0:
            return
        elapsed = max(time.perf_counter() - self.started, 1e-9)
        share = done / total
        counted = "" if self.unit == "frames" else f"{frames} frames  "
        text = (
            f"{self.label} [{'#' * int(share * 24):<24}] {done}/{total} {self.unit}  "
            f"{counted}{frames / elapsed:.1f} frames/s"
        )
        if self._tty:
            self.stream.write("\r" + text)
            if done == total:
                self.stream.write("\n")
            self.stream.flush()
            return
        decile = int(share * 10)
        if decile != self._last_decile or done == total:
            self._last_decile = decile
            self.stream.write(text + "\n")
            self.stream.flush()
