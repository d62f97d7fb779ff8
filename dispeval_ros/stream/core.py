"""The transport-free evaluation core shared by every front end (bag replay, ROS, DDS).

Front ends hand it deserialized messages by topic; it joins ground truth and every method's
DisparityImage by header stamp, scores each joined frame through the cached core engine and
returns score vectors. It never blocks and keeps no transport state, so the same object is
driven by ``dispeval bag``, the rclpy evaluator node and the Cyclone DDS front end.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Collection, Mapping
from concurrent.futures import Executor
from typing import Any

import numpy as np

from dispeval_ros.core import Camera, Reference, Scores
from dispeval_ros.core.gtfree import ImagePair, joined
from dispeval_ros.core.projection import CloudFilter, CloudProjection
from dispeval_ros.core.transforms import TransformTree, rigid_matrix
from dispeval_ros.errors import CalibrationError, ConfigurationError, DispevalError
from dispeval_ros.io.grey import stereo_grey
from dispeval_ros.io.messages import (
    DisparityFrame,
    camera_from_infos,
    disparity_from_msg,
    gt_disparity,
    image_from_msg,
    stamp_ns,
    static_transforms_from_msg,
)
from dispeval_ros.stream.clouds import cloud_disparity
from dispeval_ros.stream.config import (
    CAMERA_INFO_TYPE,
    CONFIDENCE_KEY,
    DISPARITY_TYPE,
    GT_KINDS,
    IMAGE_TYPE,
    LEFT_IMAGE_KEY,
    POINT_CLOUD_TYPE,
    RIGHT_IMAGE_KEY,
    RIGHT_VIEW_KEY,
    TF_STATIC_TOPIC,
    TF_TYPE,
    CoreConfig,
)
from dispeval_ros.stream.flicker import FlickerInput, FlickerOutcome
from dispeval_ros.stream.join import REPEAT_MEMORY_NS, FrameSet, JoinCounts, StampJoiner
from dispeval_ros.stream.motion import MotionSource
from dispeval_ros.stream.pairs import PairInput, PairOutcome, camera_view
from dispeval_ros.stream.results import FrameResult, MethodCounts

__all__ = [  # the configuration's names stay importable from here (stream.config defines them)
    "CAMERA_INFO_TYPE",
    "DISPARITY_TYPE",
    "GT_KINDS",
    "IMAGE_TYPE",
    "LEFT_IMAGE_KEY",
    "POINT_CLOUD_TYPE",
    "RIGHT_IMAGE_KEY",
    "RIGHT_VIEW_KEY",
    "TF_STATIC_TOPIC",
    "TF_TYPE",
    "CoreConfig",
    "EvaluationCore",
    "FrameResult",
    "MethodCounts",
    "negative_t_warning",
]


class EvaluationCore:
    """Join, score and report; call :meth:`push` for every message, :meth:`flush` at the end."""

    def __init__(
        self,
        config: CoreConfig,
        *,
        keep_events: bool = False,
        error_images: bool = False,
        executor: Executor | None = None,
        repeat_memory_ns: int | None = REPEAT_MEMORY_NS,
        seen_stamps: Collection[int] = (),
        wait_for_motion: bool = False,
    ) -> None:
        """``repeat_memory_ns``, ``seen_stamps``: see :class:`StampJoiner`.

        ``wait_for_motion``: ego-motion pairs wait for /tf (see :attr:`PairStage.ready`).
        """
        self.config = config
        self.error_images = error_images
        self.executor = executor
        """Where a frame's methods are scored side by side (threads: the kernels release the
        GIL); None scores them one after the other. The results are the same."""
        self.evaluator = config.evaluator()
        self.gt_free = config.ground_truth_free()
        self.confidence = config.confidence_scorers(self.evaluator)
        """Method → its confidence scorer (``confidences``): curves' sums per frame."""
        self.pairs = config.pair_stage()
        """The pair stage (``temporal``): fed in the join's order by :meth:`pair`."""
        self.flicker = config.flicker_stage()
        """The flicker windows (``flicker``): fed in the join's order by :meth:`window`."""
        self.motion: MotionSource | None = None
        """With ``egomotion``: the stream's /tf history the residual's motion comes from."""
        auxiliary = config.auxiliary()
        self.joiner: StampJoiner[Any, Any] = StampJoiner(
            [*config.methods, *auxiliary],
            config.tolerance_ns,
            config.lateness_ns,
            keep_events,
            repeat_memory=repeat_memory_ns,
            seen=seen_stamps,
        )
        self._method_of_topic = {topic: name for name, topic in config.methods.items()}
        self._method_of_topic.update({topic: key for key, topic in auxiliary.items()})
        self._infos: dict[str, Any] = {}
        self._camera: Camera | None = None
        self.transforms = TransformTree()
        self.extrinsic_lookup: Callable[[str, str], np.ndarray] | None = None
        """Point-cloud GT: ``(camera frame, cloud frame) → 4×4`` used instead of /tf_static
        (the rclpy node sets it to a tf2_ros buffer lookup)."""
        self._cloud_filter = CloudFilter.parse(config.cloud_filter)
        self.failed = dict.fromkeys(config.methods, 0)
        self._failed_lock = threading.Lock()
        if config.egomotion and self.pairs is not None:
            self.motion = MotionSource(self.transforms, TF_STATIC_TOPIC)
            self.pairs.motion = self.motion.camera_motion
            if wait_for_motion:  # a bag: /tf logged after a frame is read before its pair
                self.pairs.ready = self.motion.ready
        if self.flicker is not None and self.motion is not None:  # the static claim checked
            self.flicker.motion = self.motion.camera_motion
            self.flicker.ready = self.motion.ready if wait_for_motion else None
        self._negative_t: set[str] = set()
        """Topics already warned of a negative DisparityImage ``t`` (said once per topic)."""

    # -- input ------------------------------------------------------------------------------

    def push(self, topic: str, msg: Any, arrival: int | None = None) -> list[FrameSet[Any, Any]]:
        """Take one message; returns the joined frame sets that are ready to score.

        ``arrival`` (ns): when it arrived, the clock of the join's waits (a bag's log time,
        the receipt time live); None takes its header stamp.
        """
        if topic == self.config.gt_topic:
            return self.joiner.add_gt(stamp_ns(msg.header), msg, arrival)
        method = self._method_of_topic.get(topic)
        if method is not None:
            return self.joiner.add_estimate(method, stamp_ns(msg.header), msg, arrival)
        if topic in (self.config.left_info_topic, self.config.right_info_topic):
            self._infos[topic] = msg
            self._camera = None  # recomputed on the next frame from the latest infos
            return []
        if self.motion is not None and self.motion.takes(topic):  # /tf (and /tf_static)
            self.motion.push(topic, msg)
            return []
        if topic == self.config.tf_topic:
            # A malformed message is skipped: the frames it would connect are then reported
            # as not connected, with the frames that exist, when a cloud needs them.
            with contextlib.suppress(DispevalError):
                self.transforms.add(static_transforms_from_msg(msg, topic))
            return []
        return []

    def flush(self) -> list[FrameSet[Any, Any]]:
        """End of stream: every remaining joined frame set."""
        return self.joiner.flush()

    # -- scoring ----------------------------------------------------------------------------

    def camera(self, fallback: Any = None) -> Camera | None:
        """The camera from the latest CameraInfo pair, else from a DisparityImage's f and t."""
        left, right = self.config.left_info_topic, self.config.right_info_topic
        if left and right:
            if self._camera is None and left in self._infos and right in self._infos:
                self._camera = camera_from_infos(self._infos[left], self._infos[right], left, right)
            return self._camera
        return fallback

    def score(self, frame_set: FrameSet[Any, Any]) -> FrameResult:
        """Score every estimate of one joined frame; per-frame problems are recorded, not raised."""
        return self.scorer(frame_set)()

    def scorer(self, frame_set: FrameSet[Any, Any]) -> Callable[[], FrameResult]:
        """:meth:`score` of ``frame_set`` to run later, on any thread, as it would run now.

        The calibration (the latest CameraInfo pair) is taken now, so frames scored side by
        side, while later messages are pushed, give the same results as scored in turn.
        """
        infos = dict(self._infos)
        calibration: Camera | DispevalError | None = None
        try:
            calibration = self.camera()
        except DispevalError as error:  # raised when a frame needs it, as by score()
            calibration = error
        return lambda: self._score(frame_set, calibration, infos)

    def _score(
        self,
        frame_set: FrameSet[Any, Any],
        calibration: Camera | DispevalError | None,
        infos: Mapping[str, Any],
    ) -> FrameResult:
        """:meth:`score` with the CameraInfo pair's camera (or its error) and the infos given."""
        result = FrameResult(frame_set.stamp, {}, {})
        estimates = {
            method: entry
            for method, entry in frame_set.estimates.items()
            if method in self.config.methods
        }
        for method, (stamp, _) in estimates.items():
            if method in frame_set.arrivals:
                result.arrivals[method] = frame_set.arrivals[method]
                result.sent[method] = stamp
        for method in self.confidence:  # a confidence map joined without its estimate
            if CONFIDENCE_KEY + method in frame_set.estimates and method not in estimates:
                result.problems.append(
                    (
                        method,
                        f"{self.config.confidences[method]} at {frame_set.stamp}: a confidence "
                        f"map but no estimate on {self._topic(method)} for this frame; not "
                        "scored",
                    )
                )
        if not estimates:  # only images, right views or confidences arrived for this frame
            return result
        pair = self._image_pair(frame_set, result)
        if not self.config.has_gt:
            if pair is None:
                for method in estimates:
                    self._count_failed(method)
                return result
            camera = calibration if isinstance(calibration, Camera) else None
            given = self._score_gt_free_only(frame_set, estimates, pair, camera, result)
            return self._with_pair_input(result, None, camera or given, pair, infos)
        frames: dict[str, DisparityFrame | DispevalError] = {}
        for method, (_, msg) in estimates.items():  # each decoded once
            try:
                frames[method] = disparity_from_msg(msg, self._topic(method))
            except DispevalError as error:
                frames[method] = error
        try:
            first = frames[next(iter(estimates))]
            if isinstance(first, DispevalError):
                raise first
            topic = self._topic(next(iter(estimates)))
            camera, no_camera = self._frame_camera(first, topic, calibration, result)
            if camera is None and (self.config.pointcloud or self.config.gt_kind == "depth"):
                raise CalibrationError(no_camera)  # the ground truth itself needs the camera
            if self.config.pointcloud:
                gt = self.cloud_disparity(
                    frame_set.gt, camera, first.disparity.shape, infos
                ).disparity
            else:
                image = image_from_msg(frame_set.gt, self.config.gt_topic)
                gt = gt_disparity(
                    image, self.config.gt_kind, self.config.gt_scale, camera, self.config.gt_topic
                )
            reference = self.evaluator.reference(gt, camera)
        except DispevalError as error:
            for method in estimates:
                self._count_failed(method)
            result.problems.append((None, f"frame at {frame_set.stamp}: {error}"))
            return result
        if camera is None:  # pixel measures need no camera; the depth ones say why they are nan
            result.problems.append(
                (None, f"frame at {frame_set.stamp}: depth measures not scored: {no_camera}")
            )

        def score_method(method: str) -> FrameResult:
            return self._score_method(method, frames[method], reference, frame_set, pair)

        methods = list(estimates)
        runs = (
            self.executor.map(score_method, methods)
            if self.executor is not None and len(methods) > 1
            else map(score_method, methods)
        )
        for part in runs:  # in method order, whichever thread scored them
            result.scores.update(part.scores)
            result.estimate_stamps.update(part.estimate_stamps)
            result.problems.extend(part.problems)
            result.errors.update(part.errors)
            result.partition = part.partition or result.partition
            result.prepared.update(part.prepared)
            result.flicker_frames.update(part.flicker_frames)
            result.confidence.update(part.confidence)
        return self._with_pair_input(result, reference, reference.camera, pair, infos)

    def _with_pair_input(
        self,
        result: FrameResult,
        reference: Reference | None,
        camera: Camera | None,
        pair: ImagePair | None,
        infos: Mapping[str, Any],
    ) -> FrameResult:
        """``result`` with what the pair and flicker stages keep of its frame (if any)."""
        view: tuple[Any, str] = (None, "")
        if self.config.egomotion:  # the principal point and frame of the camera
            view = camera_view(camera, infos, self.config.left_info_topic)
        partition = None if pair is None else pair.partition
        if self.flicker is not None:
            frames = result.flicker_frames
            result.flicker_input = FlickerInput(result.stamp, frames, partition, camera, view[1])
            result.flicker_frames = {}
        if self.pairs is None:
            return result
        result.pair_input = PairInput(result.stamp, reference, result.prepared, partition, *view)
        result.prepared = {}
        return result

    def pair(self, result: FrameResult) -> FrameResult:
        """The pairs ending at a scored frame: call it on every frame, in the join's order."""
        if self.pairs is None:
            return result
        outcome = self.pairs.add(result.pair_input or PairInput(result.stamp, None, {}))
        result.pair_input = None
        result.pairs.update(outcome.scores)
        result.motion_pairs.extend(outcome.motion)
        result.pair_previous = outcome.previous
        result.problems.extend(outcome.problems)
        return result

    def finish_pairs(self) -> PairOutcome | None:
        """End of stream: the pairs still waiting for the motion source (None: no stage)."""
        return None if self.pairs is None else self.pairs.finish()

    @property
    def ordered(self) -> bool:
        """Whether scored frames must be handed to :meth:`pair` and :meth:`window` in order."""
        return self.pairs is not None or self.flicker is not None

    def window(self, result: FrameResult) -> FrameResult:
        """The flicker windows a scored frame closes (every frame, in the join's order)."""
        return result if self.flicker is None else self.flicker.take(result)

    def finish_windows(self) -> FlickerOutcome | None:
        """End of stream: the open flicker windows scored (None: no flicker)."""
        return None if self.flicker is None else self.flicker.finish()

    def _prepare(
        self, method: str, disparity: np.ndarray, terms: Mapping[str, Any],
        image: np.ndarray | None, part: FrameResult,
    ) -> None:  # fmt: skip
        """One estimate made ready for the pair and flicker stages (the same ego-motion frame)."""
        if self.pairs is not None:
            part.prepared[method] = self.pairs.prepare(disparity, **terms, image=image)
        if self.flicker is not None:
            made = part.prepared[method].motion if method in part.prepared else None
            made = made or self.flicker.prepare(disparity, **terms, image=image)
            part.flicker_frames[method] = made

    def _score_method(
        self,
        method: str,
        frame: DisparityFrame | DispevalError,
        reference: Reference,
        frame_set: FrameSet[Any, Any],
        pair: ImagePair | None,
    ) -> FrameResult:
        """One method's part of a frame's result (its scores, or its problem)."""
        stamp = frame_set.estimates[method][0]
        part = FrameResult(frame_set.stamp, {}, {})
        try:
            if isinstance(frame, DispevalError):
                raise frame
            terms = frame.scoring(reference.camera)
            gt_scores = self.evaluator.score(reference, frame.disparity, **terms)
            if reference.camera is None:
                gt_scores = gt_scores.without_camera()
            part.scores[method] = joined(
                gt_scores,
                self._gt_free_scores(method, frame, frame_set, pair, reference.camera, part),
            )
            part.estimate_stamps[method] = stamp
            if method in self.confidence:
                self._score_confidence(method, frame, reference, frame_set, part)
            image = None if pair is None else pair.left
            self._prepare(method, frame.disparity, terms, image, part)
            if self.error_images:
                part.errors[method] = self.evaluator.error_map(reference, frame.disparity, **terms)
                part.partition = reference.partition
        except DispevalError as error:
            self._count_failed(method)
            part.problems.append((method, f"{self._topic(method)} at {stamp}: {error}"))
        return part

    def _score_confidence(
        self,
        method: str,
        frame: DisparityFrame,
        reference: Reference,
        frame_set: FrameSet[Any, Any],
        part: FrameResult,
    ) -> None:
        """One estimate's confidence sums, or a problem (its other scores are kept)."""
        topic = self.config.confidences[method]
        entry = frame_set.estimates.get(CONFIDENCE_KEY + method)
        if entry is None:
            part.problems.append(
                (
                    method,
                    f"{topic} at {frame_set.stamp}: no confidence map within "
                    f"{self.config.tolerance_ns / 1e6:g} ms of this frame; its curves not scored",
                )
            )
            return
        try:
            confidence = image_from_msg(entry[1], topic).array
            part.confidence[method] = self.confidence[method].score(
                reference, frame.disparity, confidence, **frame.scoring(reference.camera)
            )
        except DispevalError as error:
            part.problems.append((method, f"{topic} at {entry[0]}: {error}; its curves not scored"))

    def _frame_camera(
        self,
        first: DisparityFrame,
        topic: str,
        calibration: Camera | DispevalError | None,
        result: FrameResult,
    ) -> tuple[Camera | None, str]:
        """The frame's camera, or None and why (then only the depth measures are lost).

        From the CameraInfo pair when configured, else from the first DisparityImage's f and
        ``|t|``; a negative ``t`` is said once per topic, as a problem row.
        """
        if self.config.left_info_topic:
            if isinstance(calibration, DispevalError):
                return None, str(calibration)
            return calibration, self._no_camera(first)
        warning = negative_t_warning(first, topic)
        with self._failed_lock:  # frames may be scored in several threads
            warn = warning is not None and topic not in self._negative_t
            if warn:
                self._negative_t.add(topic)
        if warn:
            result.problems.append((None, f"{warning} (said once for this topic)"))
        return first.camera, self._no_camera(first)

    def _no_camera(self, first: DisparityFrame) -> str:
        """Why a frame has no camera (f, B), and what gives it one."""
        left, right = self.config.left_info_topic, self.config.right_info_topic
        if left and right:
            return f"no CameraInfo pair received yet on {left} and {right}"
        return (
            f"no camera: its DisparityImage has f = {first.f:g}, t = {first.t:g} (expected "
            "finite, f > 0 and t ≠ 0); give the CameraInfo topics to take the camera from them"
        )

    # -- ground-truth-free measures ---------------------------------------------------------

    def _image_pair(self, frame_set: FrameSet[Any, Any], result: FrameResult) -> ImagePair | None:
        """The frame's left and right images checked and partitioned (None: a problem recorded).

        Without image topics: None and no problem.
        """
        if self.gt_free is None:
            return None
        left_topic, right_topic = self.config.left_image_topic, self.config.right_image_topic
        left_msg = frame_set.gt if not self.config.has_gt else _payload(frame_set, LEFT_IMAGE_KEY)
        right_msg = _payload(frame_set, RIGHT_IMAGE_KEY)
        missing = [
            topic
            for topic, msg in ((left_topic, left_msg), (right_topic, right_msg))
            if msg is None
        ]
        if missing:
            result.problems.append(
                (
                    None,
                    f"images at {frame_set.stamp}: no image on {' and '.join(map(str, missing))} "
                    f"within {self.config.tolerance_ns / 1e6:g} ms of this frame; "
                    "ground-truth-free measures not scored",
                )
            )
            return None
        try:
            left, right = stereo_grey(
                image_from_msg(left_msg, str(left_topic)),
                image_from_msg(right_msg, str(right_topic)),
                str(left_topic),
                str(right_topic),
            )
            return self.gt_free.pair(left, right)
        except DispevalError as error:
            result.problems.append(
                (
                    None,
                    f"images at {frame_set.stamp}: {error}; ground-truth-free measures not scored",
                )
            )
            return None

    def _gt_free_scores(
        self,
        method: str,
        frame: DisparityFrame,
        frame_set: FrameSet[Any, Any],
        pair: ImagePair | None,
        camera: Camera | None,
        result: FrameResult,
    ) -> Scores | None:
        """Beside GT scores: one method's GT-free scores, or empty rows and a problem.

        Empty rows keep every frame's criteria the same, so sequences still add up exactly.
        """
        if self.gt_free is None:
            return None
        if pair is None:
            return self.gt_free.empty()
        try:
            return self._score_images(method, frame, frame_set, pair, camera, result)
        except DispevalError as error:
            result.problems.append(
                (
                    method,
                    f"{self._topic(method)} at {frame_set.stamp}: {error}; "
                    "ground-truth-free measures not scored",
                )
            )
            return self.gt_free.empty()

    def _score_images(
        self,
        method: str,
        frame: DisparityFrame,
        frame_set: FrameSet[Any, Any],
        pair: ImagePair,
        camera: Camera | None,
        result: FrameResult,
    ) -> Scores:
        """Vpe (and lrc with the method's right view) of one estimate on the frame's images."""
        if self.gt_free is None:
            raise ConfigurationError(
                "no image topics configured for the ground-truth-free measures"
            )
        right_view = None
        entry = frame_set.estimates.get(RIGHT_VIEW_KEY + method)
        if entry is not None:
            right_view = disparity_from_msg(entry[1], self.config.right_views[method])
        elif method in self.config.right_views:
            result.problems.append(
                (
                    method,
                    f"{self.config.right_views[method]} at {frame_set.stamp}: no right-view "
                    "disparity for this frame; lrc not scored",
                )
            )
        return self.gt_free.score(
            pair,
            frame.disparity,
            **frame.scoring(camera),
            est_right=None if right_view is None else right_view.disparity,
            right_range=None if right_view is None else right_view.est_range,
        )

    def _score_gt_free_only(
        self,
        frame_set: FrameSet[Any, Any],
        estimates: dict[str, tuple[int, Any]],
        pair: ImagePair,
        camera: Camera | None,
        result: FrameResult,
    ) -> Camera | None:
        """Each method's GT-free scores alone (a bad one: failed); its first DisparityImage's camera."""
        given = None
        for method, (stamp, msg) in estimates.items():
            topic = self._topic(method)
            try:
                frame = disparity_from_msg(msg, topic)
                given = given or frame.camera
                result.scores[method] = self._score_images(
                    method, frame, frame_set, pair, camera, result
                )
                result.estimate_stamps[method] = stamp
                self._prepare(method, frame.disparity, frame.scoring(camera), pair.left, result)
            except DispevalError as error:
                self._count_failed(method)
                result.problems.append((method, f"{topic} at {stamp}: {error}"))
        return given

    def extrinsic(self, camera_frame: str, cloud_frame: str) -> np.ndarray:
        """The cloud → camera transform: explicit, the lookup hook, or /tf_static's chain."""
        if self.config.extrinsic is not None:
            return rigid_matrix(self.config.extrinsic, "the LiDAR extrinsic")
        if self.extrinsic_lookup is not None:
            return np.asarray(self.extrinsic_lookup(camera_frame, cloud_frame), dtype=np.float64)
        return self.transforms.lookup(camera_frame, cloud_frame)

    def cloud_disparity(
        self,
        msg: Any,
        camera: Camera | None,
        shape: tuple[int, ...],
        infos: Mapping[str, Any] | None = None,
    ) -> CloudProjection:
        """Project a PointCloud2 into the left camera (:func:`~.clouds.cloud_disparity`).

        ``infos``: the CameraInfo messages by topic (default: the latest pushed).
        """
        config, infos = self.config, self._infos if infos is None else infos
        return cloud_disparity(
            msg, config.gt_topic, config.left_info_topic, camera, shape, infos,
            self.extrinsic, self._cloud_filter,
        )  # fmt: skip

    def _count_failed(self, method: str) -> None:
        with self._failed_lock:  # score() may run in several threads
            self.failed[method] += 1

    def _topic(self, method: str) -> str:
        return self.config.methods[method]

    def counts(self) -> dict[str, MethodCounts]:
        """Matched / unmatched / dropped / failed per method so far."""
        return {
            method: _with_failed(join, self.failed[method])
            for method, join in self.joiner.counts.items()
            if method in self.failed
        }


def negative_t_warning(frame: DisparityFrame, topic: str) -> str | None:
    """What to say once about a DisparityImage whose ``t`` is negative (None: nothing)."""
    if not frame.negative_t:
        return None
    return (
        f"{topic}: its DisparityImage has t = {frame.t:g} < 0; its magnitude {abs(frame.t):g} "
        "is used as the baseline"
    )


def _payload(frame_set: FrameSet[Any, Any], key: str) -> Any:
    """The message joined under ``key`` (an image or a right view), or None."""
    entry = frame_set.estimates.get(key)
    return None if entry is None else entry[1]


def _with_failed(join: JoinCounts, failed: int) -> MethodCounts:
    return MethodCounts(join.matched - failed, join.unmatched, join.dropped, failed)
