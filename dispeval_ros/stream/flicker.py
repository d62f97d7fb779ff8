"""The flicker stage of the evaluation core: a static camera's temporal noise over windows.

Frames of a stream are handed in the join's order to :class:`FlickerStage`, which collects
each method's consecutive estimates in tumbling windows of ``size`` frames and scores each
window with :class:`~dispeval_ros.core.egomotion.FlickerWindow` (the per-pixel sample spread,
``ddof = 1``, of the estimate over the window). The rules, stated once (docs/method.md,
"Flicker of a static camera"):

- a window is ``size`` consecutive frames of a method; it starts at the first frame after the
  previous window ended;
- a frame further from the previous one than the pair gap (:data:`~.pairs.PAIR_GAP_RULE`), a
  frame whose stamp is not after the previous one's (the frame is not used), and a method
  missing at a frame (no estimate, or a scoring problem) end the method's window early: one
  problem line; the partial window is scored if it holds at least 2 frames (else one line);
- a window is scored on the ``gtfree:`` criteria of its FIRST frame's images (the residual
  of ``egomotion`` uses its earlier frame's likewise), with the left images for the
  photometric check when the stream has them (else on ``all``, every pixel);
- flicker assumes a static camera, the user's claim. With the camera's motion known
  (``egomotion``: ``/tf``), a window within which the camera moved more than
  :data:`STATIC_TRANSLATION_M` or :data:`STATIC_ROTATION_DEG` from its first frame is not
  scored (one problem line); without it nothing checks the claim.

Nothing here knows of ROS or files.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.criteria import Partition
from dispeval_ros.core.egomotion import (
    EgoMotionOptions,
    FlickerWindow,
    MotionFrame,
    TemporalSums,
    prepare_frame,
)
from dispeval_ros.errors import ConfigurationError, DispevalError
from dispeval_ros.stream.pairs import DEFAULT_PAIR_GAP_NS, MOTION_WAIT, Motion, motion_disparity

if TYPE_CHECKING:
    from dispeval_ros.stream.results import FrameResult

DEFAULT_FLICKER_WINDOW = 5
"""Frames per flicker window when ``--flicker`` is given without a number."""
FLICKER_RULE = (
    "flicker of a static camera: each method's per-pixel spread (sample std, ddof 1) over "
    "tumbling windows of N consecutive frames, on the gtfree: criteria of each window's first "
    "frame; a gap, an out-of-order stamp or a missing estimate ends a window early (scored "
    "with ≥ 2 frames); temporal noise, not accuracy"
)
"""The option's meaning, as every front end's help says it."""
STATIC_TRANSLATION_M = 0.005
"""With the camera's motion known: a window is static while the camera stays within 5 mm of
where it was at the window's first frame (odometry noise of a standing robot is below it; a
5 mm move at 2 m changes a 100 px disparity by 0.25 px)."""
STATIC_ROTATION_DEG = 0.05
"""… and within 0.05° of its first orientation (≈ 0.5 px at f = 600 px)."""


@dataclass(frozen=True)
class FlickerInput:
    """What one scored frame leaves for the flicker windows.

    ``frames``: each method scored on the frame, its estimate prepared; ``partition``: the
    ground-truth-free criteria of its images (None: ``all``); ``camera``: f and B (for the
    spread in depth); ``camera_frame``: the left camera's frame (for the motion check).
    """

    stamp: int
    frames: Mapping[str, MotionFrame]
    partition: Partition | None = None
    camera: Camera | None = None
    camera_frame: str = ""


@dataclass(frozen=True)
class FlickerScore:
    """One method's flicker over one window: from ``start`` to ``stamp`` (first, last frame)."""

    method: str
    start: int
    stamp: int
    frames: int
    sums: TemporalSums


@dataclass
class FlickerOutcome:
    """The windows scored now and the problems met."""

    windows: list[FlickerScore] = field(default_factory=list)
    problems: list[tuple[str | None, str]] = field(default_factory=list)


@dataclass
class _Open:
    """A method's window being filled: its first frame's input and the frames so far."""

    first: FlickerInput
    window: FlickerWindow | None
    stamps: list[int]


def window_text(method: str, stamps: list[int]) -> str:
    """``sgbm: flicker window 100 → 300 (3 frames)``, the wording of every flicker problem."""
    count = f"{len(stamps)} frame{'' if len(stamps) == 1 else 's'}"
    return f"{method}: flicker window {stamps[0]} → {stamps[-1]} ({count})"


class FlickerStage:
    """Tumbling windows of each method's consecutive frames, scored as they close.

    Not thread-safe: call :meth:`add` from one thread, in the join's order of the frames;
    :meth:`prepare` may run on any thread.
    """

    def __init__(
        self,
        size: int = DEFAULT_FLICKER_WINDOW,
        gap_ns: int = DEFAULT_PAIR_GAP_NS,
        options: EgoMotionOptions | None = None,
    ) -> None:
        if not isinstance(size, int) or size < 2:
            raise ConfigurationError(
                f"a flicker window needs at least 2 frames (the spread of one is undefined), "
                f"got {size!r}"
            )
        self.size = size
        self.gap_ns = gap_ns
        self.options = options or EgoMotionOptions()
        self.motion: Motion | None = None
        """The camera's motion (``egomotion``: the stream's /tf) to check the static claim
        with; None: not checked (flicker assumes a static camera)."""
        self.ready: Callable[[int, str], bool] | None = None
        """``ready(stamp_ns, camera_frame)``: whether :attr:`motion` can answer up to it."""
        self._open: dict[str, _Open] = {}
        self._last: int | None = None
        self._waiting: deque[tuple[str, _Open]] = deque()
        self._methods: set[str] = set()

    def prepare(
        self,
        estimate: np.ndarray,
        est_range: tuple[float, float] | None,
        est_offset: float,
        image: np.ndarray | None = None,
    ) -> MotionFrame:
        """One estimate made ready for its window (any thread), as the ego-motion stage does."""
        return prepare_frame(
            motion_disparity(estimate, est_range, est_offset),
            image,
            valid_range=(-np.inf, np.inf),
            options=self.options,
        )

    def add(self, frame: FlickerInput) -> FlickerOutcome:
        """Add one frame to each method's window; the windows that close are scored."""
        out = FlickerOutcome()
        last, stamp = self._last, frame.stamp
        if last is not None and stamp <= last:
            out.problems.append(
                (
                    None,
                    f"frame at {stamp}: its stamp is not after the previous frame's ({last}): "
                    "not used for flicker; it ends every flicker window",
                )
            )
            for method in list(self._open):  # (the line above says why)
                self._close(method, f"the next frame ({stamp}) is out of order", out, say=False)
            self._last = stamp
            self._resolve(out)
            return out
        self._last = stamp
        gap = None if last is None else stamp - last
        for method in list(self._open):
            if gap is not None and gap > self.gap_ns:
                reason = (
                    f"the next frame ({stamp}) is {gap / 1e6:g} ms later, more than the pair gap "
                    f"{self.gap_ns / 1e6:g} ms"
                )
                self._close(method, reason, out)
            elif method not in frame.frames:
                self._close(method, f"{method} not scored at {stamp}", out)
        for method, prepared in frame.frames.items():
            current = self._open.get(method)
            self._methods.add(method)
            if current is None:
                current = self._open[method] = _Open(frame, None, [])
                if frame.camera is not None:
                    current.window = FlickerWindow(frame.camera, self.options)
            current.stamps.append(stamp)
            if current.window is not None:
                try:
                    current.window.add(prepared)
                except DispevalError as error:  # (another size, an image missing)
                    current.stamps.pop()
                    self._close(method, f"{method} at {stamp} does not fit it: {error}", out)
                    continue
            if len(current.stamps) == self.size:
                self._close(method, None, out)
        self._resolve(out)
        return out

    def take(self, result: FrameResult) -> FrameResult:
        """:meth:`add` of a scored frame's input; its windows and problems go on ``result``.

        A bag's unit takes the frames it keeps only: windows never span units.
        """
        outcome = self.add(result.flicker_input or FlickerInput(result.stamp, {}))
        result.flicker_input = None
        result.flicker.extend(outcome.windows)
        result.problems.extend(outcome.problems)
        return result

    def finish(self) -> FlickerOutcome:
        """End of stream: every open window closed and every waiting one scored."""
        out = FlickerOutcome()
        for method in list(self._open):
            self._close(method, None, out)
        self._resolve(out, final=True)
        return out

    def _close(
        self, method: str, reason: str | None, out: FlickerOutcome, *, say: bool = True
    ) -> None:
        """End ``method``'s window and queue it; ``reason``: why early (one line if ``say``)."""
        current = self._open.pop(method)
        if not current.stamps:
            return
        what = window_text(method, current.stamps)
        if len(current.stamps) < 2:
            cause = f"ended by {reason}" if reason else "ended by the end of the stream"
            out.problems.append((method, f"{what} {cause}: not scored (at least 2 needed)"))
            return
        if reason is not None and say:
            out.problems.append((method, f"{what} ended early: {reason}"))
        if current.window is None:
            out.problems.append(
                (method, f"{what} not scored: no camera (f, B) for its first frame")
            )
            return
        self._waiting.append((method, current))

    def _resolve(self, out: FlickerOutcome, final: bool = False) -> None:
        """Score the closed windows whose motion is known (all of them if ``final``)."""
        while self._waiting:
            method, current = self._waiting[0]
            ready = (
                self.motion is None
                or self.ready is None
                or self.ready(current.stamps[-1], current.first.camera_frame)
            )
            bound = MOTION_WAIT * max(1, len(self._methods))  # windows of every method
            if not (ready or final or len(self._waiting) > bound):
                break
            self._waiting.popleft()
            self._score(method, current, out)

    def _score(self, method: str, current: _Open, out: FlickerOutcome) -> None:
        """One closed window's sums, unless the camera moved within it."""
        what = window_text(method, current.stamps)
        try:
            moved = self._moved(current)
            if moved is not None:
                out.problems.append((method, f"{what} not scored: {moved}"))
                return
            assert current.window is not None  # (queued only with a window)
            sums = current.window.sums(current.first.partition)
        except DispevalError as error:
            out.problems.append((method, f"{what} not scored: {error}"))
            return
        out.windows.append(
            FlickerScore(method, current.stamps[0], current.stamps[-1], len(current.stamps), sums)
        )

    def _moved(self, current: _Open) -> str | None:
        """Why the camera is not static over the window (None: it is, or nothing checks it)."""
        if self.motion is None:
            return None
        frame = current.first.camera_frame
        if not frame:
            raise ConfigurationError(
                "the camera's frame is unknown (no left CameraInfo): its motion cannot be checked"
            )
        start = current.stamps[0]
        for stamp in current.stamps[1:]:
            motion = self.motion(frame, start, stamp)
            shift = float(np.linalg.norm(motion[:3, 3]))
            cosine = (float(np.trace(motion[:3, :3])) - 1.0) / 2.0
            turn = math.degrees(math.acos(min(1.0, max(-1.0, cosine))))
            if shift > STATIC_TRANSLATION_M or turn > STATIC_ROTATION_DEG:
                return (
                    f"the camera moved {shift * 1e3:.3g} mm and turned {turn:.3g}° from "
                    f"{start} to {stamp} (/tf), more than a static camera's "
                    f"{STATIC_TRANSLATION_M * 1e3:g} mm and {STATIC_ROTATION_DEG:g}°"
                )
        return None
