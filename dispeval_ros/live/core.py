"""The transport-free evaluation core shared by every front end (bag replay, ROS, DDS).

Front ends hand it deserialized messages by topic; it joins ground truth and every method's
DisparityImage by header stamp, scores each joined frame through the cached core engine and
returns score vectors. It never blocks and keeps no transport state, so the same object is
driven by ``dispeval bag``, the rclpy evaluator node and the Cyclone DDS front end.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dispeval_ros.core import Camera, Evaluator, Partition, Scores
from dispeval_ros.core.measures import SEQUENCE_MEASURES
from dispeval_ros.errors import ConfigurationError, DispevalError
from dispeval_ros.io.messages import (
    camera_from_infos,
    disparity_from_msg,
    gt_disparity,
    image_from_msg,
    stamp_ns,
)
from dispeval_ros.live.join import FrameSet, JoinCounts, StampJoiner

DISPARITY_TYPE = "stereo_msgs/msg/DisparityImage"
IMAGE_TYPE = "sensor_msgs/msg/Image"
CAMERA_INFO_TYPE = "sensor_msgs/msg/CameraInfo"
GT_KINDS = ("disparity", "depth")


@dataclass(frozen=True)
class CoreConfig:
    """What to evaluate: topics, ground-truth encoding, evaluation options, sync."""

    methods: Mapping[str, str]
    gt_topic: str
    gt_kind: str = "disparity"
    gt_scale: float | None = None
    left_info_topic: str | None = None
    right_info_topic: str | None = None
    criteria: Sequence[str] = ("all", "visibility", "depth")
    measures: Sequence[str] | None = None
    missing: str = "interpolate"
    delta: float = 1.0
    mu: float = 0.01
    tolerance_ns: int = 10_000_000
    lateness_ns: int = 1_000_000_000

    def __post_init__(self) -> None:
        if not self.methods:
            raise ConfigurationError("no method given; name at least one NAME=TOPIC")
        if self.gt_kind not in GT_KINDS:
            raise ConfigurationError(
                f"ground-truth kind must be one of {', '.join(GT_KINDS)}, got '{self.gt_kind}'"
            )
        topics = list(self.methods.values())
        if len(set(topics)) != len(topics):
            raise ConfigurationError("two methods read the same topic")
        if self.gt_topic in topics:
            raise ConfigurationError(
                f"the ground-truth topic {self.gt_topic} is also a method's topic"
            )
        if (self.left_info_topic is None) != (self.right_info_topic is None):
            raise ConfigurationError(
                "give both the left and the right CameraInfo topics, or neither"
            )

    @property
    def topics(self) -> dict[str, str]:
        """Every subscribed topic → the message type expected on it."""
        expected = {self.gt_topic: IMAGE_TYPE}
        expected.update(dict.fromkeys(self.methods.values(), DISPARITY_TYPE))
        if self.left_info_topic and self.right_info_topic:
            expected[self.left_info_topic] = CAMERA_INFO_TYPE
            expected[self.right_info_topic] = CAMERA_INFO_TYPE
        return expected

    def as_record(self) -> dict[str, object]:
        """The configuration as plain values (stored with results, compared on --resume)."""
        return {
            "methods": dict(self.methods),
            "gt_topic": self.gt_topic,
            "gt_kind": self.gt_kind,
            "gt_scale": self.gt_scale,
            "camera_info": [self.left_info_topic, self.right_info_topic],
            "criteria": list(self.criteria),
            "measures": list(self.measures or []),
            "missing": self.missing,
            "delta": self.delta,
            "mu": self.mu,
            "tolerance_ns": self.tolerance_ns,
            "lateness_ns": self.lateness_ns,
        }

    def evaluator(self) -> Evaluator:
        """The core evaluator these options describe (measures default to the summable ones)."""
        measures = self.measures if self.measures is not None else SEQUENCE_MEASURES
        return Evaluator(self.criteria, measures, self.missing, self.delta, self.mu)


@dataclass
class FrameResult:
    """Scores of every method that delivered an estimate for one ground-truth frame."""

    stamp: int
    scores: dict[str, Scores]
    estimate_stamps: dict[str, int]
    problems: list[tuple[str | None, str]] = field(default_factory=list)
    errors: dict[str, np.ndarray] = field(default_factory=dict)
    """With ``error_images``: per method, the absolute error (float32, NaN where not evaluated)."""
    partition: Partition | None = None
    """The criteria of this frame's ground truth (to render error images with criteria)."""


@dataclass
class MethodCounts:
    """Join counts plus frames that were joined but could not be scored."""

    matched: int = 0
    unmatched: int = 0
    dropped: int = 0
    failed: int = 0


class EvaluationCore:
    """Join, score and report; call :meth:`push` for every message, :meth:`flush` at the end."""

    def __init__(
        self, config: CoreConfig, *, keep_events: bool = False, error_images: bool = False
    ) -> None:
        self.config = config
        self.error_images = error_images
        self.evaluator = config.evaluator()
        self.joiner: StampJoiner[Any, Any] = StampJoiner(
            list(config.methods), config.tolerance_ns, config.lateness_ns, keep_events
        )
        self._method_of_topic = {topic: name for name, topic in config.methods.items()}
        self._infos: dict[str, Any] = {}
        self._camera: Camera | None = None
        self.failed = dict.fromkeys(config.methods, 0)
        self._failed_lock = threading.Lock()

    # -- input ------------------------------------------------------------------------------

    def push(self, topic: str, msg: Any) -> list[FrameSet[Any, Any]]:
        """Take one message; returns the joined frame sets that are ready to score."""
        if topic == self.config.gt_topic:
            return self.joiner.add_gt(stamp_ns(msg.header), msg)
        method = self._method_of_topic.get(topic)
        if method is not None:
            return self.joiner.add_estimate(method, stamp_ns(msg.header), msg)
        if topic in (self.config.left_info_topic, self.config.right_info_topic):
            self._infos[topic] = msg
            self._camera = None  # recomputed on the next frame from the latest infos
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
        result = FrameResult(frame_set.stamp, {}, {})
        try:
            first = disparity_from_msg(
                next(iter(frame_set.estimates.values()))[1],
                self._topic(next(iter(frame_set.estimates))),
            )
            camera = self.camera(first.camera)
            image = image_from_msg(frame_set.gt, self.config.gt_topic)
            gt = gt_disparity(
                image, self.config.gt_kind, self.config.gt_scale, camera, self.config.gt_topic
            )
            reference = self.evaluator.reference(gt, camera)
        except DispevalError as error:
            for method in frame_set.estimates:
                self._count_failed(method)
            result.problems.append((None, f"ground truth at {frame_set.stamp}: {error}"))
            return result
        for method, (stamp, msg) in frame_set.estimates.items():
            topic = self._topic(method)
            try:
                frame = disparity_from_msg(msg, topic)
                result.scores[method] = self.evaluator.score(
                    reference, frame.disparity, est_range=frame.est_range
                )
                result.estimate_stamps[method] = stamp
                if self.error_images:
                    result.errors[method] = self.evaluator.error_map(
                        reference, frame.disparity, frame.est_range
                    )
                    result.partition = reference.partition
            except DispevalError as error:
                self._count_failed(method)
                result.problems.append((method, f"{topic} at {stamp}: {error}"))
        return result

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
        }


def _with_failed(join: JoinCounts, failed: int) -> MethodCounts:
    return MethodCounts(join.matched - failed, join.unmatched, join.dropped, failed)
