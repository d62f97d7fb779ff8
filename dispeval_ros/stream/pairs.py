"""The pair stage of the evaluation core: temporal measures over consecutive frames of a stream.

Frames of a stream are scored one by one (side by side, possibly), then handed in the join's
order to :class:`PairStage`, which keeps the last of them and scores each method's pair
(previous frame, this frame) with :class:`~dispeval_ros.core.temporal.TemporalScorer`. The
rules, stated once (docs/method.md, "Temporal measures in bags and live"):

- the pair is (the frame the join produced just before, this frame), for every method scored
  on both; the previous frame is always the last frame produced, whatever became of it, so the
  pairs depend only on each two neighbouring frames (a bag cut into units gives the same pairs);
- a method scored on the previous frame but not on this one (no estimate, or a scoring
  problem) ends its run of pairs: one problem line;
- frames further apart than the pair gap (:data:`DEFAULT_PAIR_GAP_NS`, :data:`PAIR_GAP_RULE`)
  are not paired (one problem line per method), nor is a frame whose stamp is not after the
  previous one's (one problem line);
- the ground truth of both frames is used as ``eval --scene --temporal`` uses it (dense GT:
  the pixels with GT in both frames).

With ``egomotion`` the same pairs also give each method's ego-motion residual
(:func:`~dispeval_ros.core.egomotion.egomotion_residual`: ground-truth-free temporal noise, on
the ``gtfree:`` criteria of the earlier frame's images), the camera's motion between the two
stamps taken from :attr:`PairStage.motion`; a pair whose motion cannot be looked up is one
problem line. Where both frames' ground truth is a projected LiDAR scan (``drift``), the same
pair and motion also give each method's LiDAR drift between the scans
(:func:`~dispeval_ros.core.lidar_drift.lidar_drift`, on the ``drift:`` criteria of the earlier
scan's partition, as ``eval --scene --egomotion`` scores it). A pair waits (up to
:data:`MOTION_WAIT` pairs) until :attr:`PairStage.ready` says the motion source holds its
later stamp (``/tf`` is often logged after the frame), and :meth:`PairStage.finish` scores
those still waiting at the end of a stream. Nothing here knows of ROS or files.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.criteria import Partition
from dispeval_ros.core.egomotion import (
    EgoMotionOptions,
    MotionFrame,
    PinholeCamera,
    TemporalSums,
    egomotion_residual,
    prepare_frame,
)
from dispeval_ros.core.evaluator import Evaluator, Reference
from dispeval_ros.core.lidar_drift import DriftOptions, DriftSums, coded_estimate, lidar_drift
from dispeval_ros.core.temporal import PairScores, PreparedEstimate, TemporalScorer
from dispeval_ros.errors import ConfigurationError, DispevalError
from dispeval_ros.io.messages import rectified_camera_from_info

DEFAULT_PAIR_GAP_NS = 250_000_000
"""Frames further apart than this (stamps) are not a pair: a camera at 4 Hz or more has its
consecutive frames closer; a longer gap is a lost frame or a pause in the stream."""
PAIR_GAP_RULE = (
    "consecutive ground-truth frames whose stamps are further apart are not paired (a lost "
    "frame or a pause ends the run of pairs)"
)
"""The pair gap's meaning, as every front end's help says it."""
DRIFT_RULE = (
    "with point-cloud ground truth also each method's LiDAR drift between scans over the same "
    "pairs (drift:* criteria: the change of its error from scan t to scan t+1, temporal noise, "
    "not accuracy)"
)
"""When the ego-motion pairs also give the LiDAR drift, as every front end's help says it."""
MOTION_WAIT = 8
"""Ego-motion pairs kept waiting for the motion source at most (then the oldest is scored
with what it holds): bounds memory when ``/tf`` lags or never comes."""
LIVE_MOTION_GRACE_S = 0.25
"""Live, a pair waits this long (s) for the /tf at its later stamp (odometry is often
published a few ms after the image), then is scored with what the history holds."""
LIVE_MOTION_STALE_NS = 500_000_000
"""Live, /tf whose newest sample is further behind a frame than this is not waited for: it
has stopped (or never reaches the camera), and waiting would only slow every frame."""
Motion = Callable[[str, int, int], np.ndarray]
"""``motion(camera_frame, t0_ns, t1_ns)``: the pose of the camera at ``t1`` in its frame at
``t0`` (4×4; it maps points of the camera frame at ``t1`` into the frame at ``t0``), the
convention of :func:`~dispeval_ros.core.egomotion.camera_motion` and of
``TransformHistory.camera_motion``; raises :class:`DispevalError` (one line) when it cannot."""


@dataclass(frozen=True)
class MethodPairInput:
    """One method's estimate of one frame, made ready for the pairs it is in (any thread)."""

    prepared: PreparedEstimate | None = None
    """For the pair measures with GT (``temporal``)."""
    motion: MotionFrame | None = None
    """For the ego-motion residual (``egomotion``)."""
    coded: np.ndarray | None = None
    """For the LiDAR drift (``drift``): the estimate coded under the run's missing policy."""


@dataclass(frozen=True)
class PairInput:
    """What one scored frame leaves for its pairs: its references and each method's estimate.

    ``reference`` is None when the frame's ground truth could not be scored (or there is
    none); ``estimates`` holds the methods scored on the frame. ``partition`` (the
    ground-truth-free criteria of its images), ``camera`` and ``camera_frame`` serve the
    ego-motion residual.
    """

    stamp: int
    reference: Reference | None
    estimates: Mapping[str, MethodPairInput]
    partition: Partition | None = None
    camera: PinholeCamera | None = None
    camera_frame: str = ""


@dataclass(frozen=True)
class MotionPair:
    """One method's ego-motion residual of the pair (``previous``, ``stamp``)."""

    stamp: int
    previous: int
    method: str
    sums: TemporalSums
    drift: DriftSums | None = None
    """The LiDAR drift of the same pair (None: not scored, e.g. no LiDAR ground truth)."""


@dataclass(frozen=True)
class PairOutcome:
    """The pairs ending at one frame: method → scores, the previous frame's stamp, problems."""

    previous: int | None
    scores: dict[str, PairScores]
    problems: list[tuple[str | None, str]]
    motion: list[MotionPair] = field(default_factory=list)
    """The ego-motion residuals scored now (``egomotion``): of this pair, and of earlier ones
    that waited for the motion source."""


def no_pair(method: str, previous: int, stamp: int, reason: str) -> str:
    """``sgbm: no pair 100 → 300: …``, the wording of ``eval --scene --temporal``'s gaps."""
    return f"{method}: no pair {previous} → {stamp}: {reason}"


class PairStage:
    """Keeps the last frame of a stream and scores the pairs ending at each next frame.

    ``preset``: the pair measures with GT (None: not scored); ``egomotion``: the ego-motion
    residual's options (None: not scored); ``drift``: the LiDAR drift's, with ``egomotion``
    and a LiDAR ground truth (None: not scored). Not thread-safe: call :meth:`add` from one thread,
    in the join's order of the frames; :meth:`prepare` may run on any thread.
    """

    def __init__(
        self,
        evaluator: Evaluator,
        preset: str | None,
        gap_ns: int = DEFAULT_PAIR_GAP_NS,
        egomotion: EgoMotionOptions | None = None,
        drift: DriftOptions | None = None,
    ) -> None:
        self.scorer = None if preset is None else TemporalScorer(evaluator, preset=preset)
        self.egomotion = egomotion
        self.drift = drift if egomotion is not None else None
        self.gap_ns = gap_ns
        self.motion: Motion | None = None
        """Where the ego-motion residual takes the camera's motion from (the front end sets
        it: the stream's /tf history, or a test's exact motion)."""
        self.ready: Callable[[int, str], bool] | None = None
        """``ready(stamp_ns, camera_frame)``: whether :attr:`motion` can already answer up to
        that stamp (None: always; ``TransformHistory.ready``)."""
        self._previous: PairInput | None = None
        self._waiting: deque[tuple[PairInput, PairInput, list[str]]] = deque()

    def prepare(
        self,
        estimate: np.ndarray,
        est_range: tuple[float, float] | None,
        est_offset: float,
        image: np.ndarray | None = None,
    ) -> MethodPairInput:
        """One estimate made ready for both pairs it is in (any thread).

        ``image``: the frame's left grey image, for the ego-motion residual's photometric
        mask (None: not applied).
        """
        prepared = None
        if self.scorer is not None:
            prepared = self.scorer.prepare(estimate, est_range=est_range, est_offset=est_offset)
        motion, coded = None, None
        if self.egomotion is not None:
            disparity = motion_disparity(estimate, est_range, est_offset)
            motion = prepare_frame(
                disparity, image, valid_range=(-np.inf, np.inf), options=self.egomotion
            )
            if self.drift is not None:
                coded = coded_estimate(disparity, self.drift.missing)
        return MethodPairInput(prepared, motion, coded)

    def add(self, frame: PairInput) -> PairOutcome:
        """The pairs (previous frame, ``frame``) of every method; ``frame`` becomes the previous."""
        previous, self._previous = self._previous, frame
        if previous is None:
            return PairOutcome(None, {}, [], self._resolve([]))
        stamp, before = frame.stamp, previous.stamp
        problems: list[tuple[str | None, str]] = []
        if stamp <= before:
            reason = f"its stamp is not after the previous frame's ({before}): no pair with it"
            problems.append((None, f"frame at {stamp}: {reason}"))
            return PairOutcome(before, {}, problems, self._resolve(problems))
        gap = stamp - before
        for method in previous.estimates:
            if method not in frame.estimates:
                problems.append(
                    (method, no_pair(method, before, stamp, f"{method} not scored at {stamp}"))
                )
            elif gap > self.gap_ns:
                reason = (
                    f"the frames are {gap / 1e6:g} ms apart, more than the pair gap "
                    f"{self.gap_ns / 1e6:g} ms"
                )
                problems.append((method, no_pair(method, before, stamp, reason)))
        pairable = [m for m in previous.estimates if m in frame.estimates]
        if gap > self.gap_ns or not pairable:
            return PairOutcome(before, {}, problems, self._resolve(problems))
        scores = self._tepe(previous, frame, pairable, problems)
        if self.egomotion is not None:
            self._waiting.append((previous, frame, pairable))
        return PairOutcome(before, scores, problems, self._resolve(problems))

    def finish(self) -> PairOutcome:
        """End of stream: the ego-motion pairs still waiting, scored with what the source holds."""
        problems: list[tuple[str | None, str]] = []
        return PairOutcome(None, {}, problems, self._resolve(problems, final=True))

    def _resolve(
        self, problems: list[tuple[str | None, str]], final: bool = False
    ) -> list[MotionPair]:
        """Score the waiting ego-motion pairs whose motion is known (all of them if ``final``)."""
        done: list[MotionPair] = []
        while self._waiting:
            previous, frame, methods = self._waiting[0]
            ready = self.ready is None or self.ready(frame.stamp, previous.camera_frame)
            if not (ready or final or len(self._waiting) > MOTION_WAIT):
                break
            self._waiting.popleft()
            done += self._egomotion(previous, frame, methods, problems)
        return done

    def _tepe(
        self,
        previous: PairInput,
        frame: PairInput,
        methods: list[str],
        problems: list[tuple[str | None, str]],
    ) -> dict[str, PairScores]:
        """The pair measures with GT of ``methods`` (both frames' GT scored)."""
        scores: dict[str, PairScores] = {}
        if self.scorer is None or previous.reference is None or frame.reference is None:
            return scores
        before, stamp = previous.stamp, frame.stamp
        try:
            pair = self.scorer.pair(previous.reference, frame.reference)
        except DispevalError as error:
            problems.extend((m, no_pair(m, before, stamp, str(error))) for m in methods)
            return scores
        for method in methods:
            first, second = previous.estimates[method].prepared, frame.estimates[method].prepared
            if first is None or second is None:
                continue
            try:
                scores[method] = self.scorer.score(pair, first, second)
            except DispevalError as error:
                problems.append((method, no_pair(method, before, stamp, str(error))))
        return scores

    def _egomotion(
        self,
        previous: PairInput,
        frame: PairInput,
        methods: list[str],
        problems: list[tuple[str | None, str]],
    ) -> list[MotionPair]:
        """The ego-motion residual of ``methods``; an unknown motion is one line for all."""
        sums: list[MotionPair] = []
        if self.egomotion is None:
            return sums
        before, stamp = previous.stamp, frame.stamp
        where = f"no ego-motion pair {before} → {stamp}"
        try:
            if self.motion is None:
                raise ConfigurationError("no source of the camera's motion (/tf) is set")
            if previous.camera is None:
                raise ConfigurationError(
                    "no camera principal point (the left CameraInfo) for the earlier frame"
                )
            moved = self.motion(previous.camera_frame, before, stamp)
        except DispevalError as error:
            problems.append((None, f"{where}: {error}"))
            return sums
        for method in methods:
            first, second = previous.estimates[method].motion, frame.estimates[method].motion
            if first is None or second is None:
                continue
            try:
                residual = egomotion_residual(
                    first, second, moved, previous.camera, previous.partition, self.egomotion
                )
            except DispevalError as error:
                problems.append((method, f"{method}: {where}: {error}"))
                continue
            try:
                drift = self._drift(previous, frame, method, moved)
            except DispevalError as error:  # the residual is kept: the drift alone is lost
                problems.append((method, f"{method}: no LiDAR drift {before} → {stamp}: {error}"))
                drift = None
            sums.append(MotionPair(stamp, before, method, residual, drift))
        return sums

    def _drift(
        self, previous: PairInput, frame: PairInput, method: str, moved: np.ndarray
    ) -> DriftSums | None:
        """One method's LiDAR drift of the pair (None: no drift options or no scan in either)."""
        first, second = previous.estimates[method].coded, frame.estimates[method].coded
        scan, target = previous.reference, frame.reference
        if self.drift is None or first is None or second is None or scan is None:
            return None
        if target is None or previous.camera is None:
            return None
        return lidar_drift(
            scan.gt, target.gt, first, second, moved, previous.camera, scan.partition, self.drift
        )


def camera_view(
    camera: Camera | None, infos: Mapping[str, Any], left: str | None
) -> tuple[PinholeCamera | None, str]:
    """The left camera with its principal point, and its frame, from its CameraInfo.

    ``(None, "")`` without a camera or a left CameraInfo (the pair then says so).
    """
    if camera is None or left is None or left not in infos:
        return None, ""
    try:
        view = rectified_camera_from_info(infos[left], left)
    except DispevalError:
        return None, ""
    cx, cy = float(view.projection[0, 2]), float(view.projection[1, 2])
    return PinholeCamera(camera, cx, cy), view.frame_id


def motion_disparity(
    estimate: np.ndarray, est_range: tuple[float, float] | None, est_offset: float
) -> np.ndarray:
    """The estimate as the ego-motion residual reads it: ``value − offset``, NaN where missing.

    Valid as :func:`~dispeval_ros.core.evaluator.estimate_coding` tells it, on the values as
    published: inside ``est_range``; a lower end of −inf (or no range): > 0 instead.
    """
    values = np.asarray(estimate, dtype=np.float32)
    lo, hi = est_range if est_range is not None else (-np.inf, np.inf)
    with np.errstate(invalid="ignore"):
        low = values > 0 if lo == -np.inf else values >= lo
        valid = low & (values <= hi) & np.isfinite(values)
    return np.where(valid, values - np.float32(est_offset), np.float32(np.nan))
