"""The live evaluator on DDS: ROS 2 topics in, scores out, as the rclpy evaluator node does.

Subscriptions (best-effort, keep-last: REP 2003 sensor data, so any publisher matches) feed
:class:`~dispeval_ros.stream.runner.LiveEvaluator` from one reader thread; every scored frame is
published

- on ``/dispeval/scores`` as a ``diagnostic_msgs/msg/DiagnosticArray`` (``header.stamp`` = the
  ground-truth stamp; one ``DiagnosticStatus`` per method from
  :func:`~dispeval_ros.stream.vectors.scores_status`, with the exact sums a summarizer needs;
  a frame's problems as ERROR statuses without values, named after the method or
  ``ground_truth``), reliable;
  and the delivery record of :mod:`~dispeval_ros.stream.delivery` (this evaluator's id, the
  array's index, its per-method counts so far), as the rclpy evaluator sends them;
- on ``/dispeval/<method>/vector`` as a ``std_msgs/msg/Float64MultiArray`` (the labelled
  numbers of :func:`~dispeval_ros.stream.vectors.score_vector`).

A ground-truth stamp that jumps back by more than ``tolerance + lateness`` (and at least 1 s)
means the stream started again (a looping player, a robot restarted with sim time): the frames
waiting are scored, and a fresh join starts (with the latest CameraInfo pair), so the new pass
is not dropped as late.
"""

from __future__ import annotations

import os
import secrets
import threading
from collections import deque
from collections.abc import Callable

import numpy as np

from dispeval_ros.core import Camera
from dispeval_ros.dds.diagnostics import diagnostic_array, vector_message
from dispeval_ros.dds.transport import DdsTransport, Received
from dispeval_ros.dds.wire import (
    DIAGNOSTIC_ARRAY,
    DYNAMIC_TF,
    FLOAT64_MULTI_ARRAY,
    RESULTS,
    SENSOR_DATA,
    STATIC_TF,
    QosProfile,
    vector_topic,
)
from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.stream.config import QUEUE_SIZE, TF_STATIC_TOPIC, TF_TOPIC, TF_TYPE
from dispeval_ros.stream.core import CoreConfig, FrameResult, MethodCounts
from dispeval_ros.stream.delivery import Delivery, delivery_record
from dispeval_ros.stream.runner import LiveEvaluator
from dispeval_ros.stream.topics import SCORES_TOPIC
from dispeval_ros.stream.vectors import (
    AlarmThresholds,
    StatusRecord,
    problem_statuses,
    result_statuses,
    score_vector,
    vector_labels,
)

VECTOR_QOS = QosProfile(reliable=True, depth=10)
ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
MIN_RESTART_NS = 1_000_000_000


def warm_up(config: CoreConfig) -> None:
    """Score one small synthetic frame, so compiled kernels are loaded before frames arrive."""
    evaluator = config.evaluator()
    rows, cols = np.mgrid[0:48, 0:64]
    gt = (8.0 + 0.2 * cols + 0.1 * rows).astype(np.float32)
    estimate = gt + np.float32(0.3)
    estimate[::7, ::5] = -1.0
    camera = Camera(f=100.0, baseline=0.5)
    reference = evaluator.reference(gt, camera)
    evaluator.score(reference, estimate)
    free = config.ground_truth_free()
    if free is not None:  # the ground-truth-free kernels too
        image = (cols * 4 % 256).astype(np.uint8)
        free.score(free.pair(image, image), estimate)


def subscription_qos(topic: str, msgtype: str, sensor: QosProfile) -> QosProfile:
    """A topic's reader QoS: transforms as tf2_ros's listeners subscribe them, else ``sensor``.

    ``/tf_static`` latched (a late reader still gets the mounts), ``/tf`` reliable keep-last
    100 (the bursts of a robot's transforms are not lost).
    """
    if msgtype == TF_TYPE and topic == TF_STATIC_TOPIC:
        return STATIC_TF
    if msgtype == TF_TYPE and topic == TF_TOPIC:
        return DYNAMIC_TF
    return sensor


class DdsEvaluator:
    """Subscribe to the configured topics, score, publish scores and vectors.

    One thread takes and decodes the messages, one scores (the live evaluator's), one
    publishes, so scoring never waits for serialisation. ``on_result`` (optional) sees every
    published :class:`FrameResult` (in the publishing thread).
    """

    def __init__(
        self,
        transport: DdsTransport,
        config: CoreConfig,
        *,
        alarms: AlarmThresholds | None = None,
        queue_size: int = QUEUE_SIZE,
        subscription: QosProfile = SENSOR_DATA,
        on_result: Callable[[FrameResult], None] | None = None,
        on_error: Callable[[str], None] | None = None,
        odometry: str | None = None,
        mount: np.ndarray | None = None,
    ) -> None:
        """``odometry``, ``mount``: an odometry-only robot's motion and camera mount.

        With ``egomotion``: the nav_msgs/Odometry topic read instead of /tf, and the camera on
        its child frame (4×4) instead of /tf_static.
        """
        self.transport = transport
        self.odometry = odometry
        self.mount = mount
        self.config = config
        self.alarms = alarms
        self.queue_size = queue_size
        self.on_result = on_result
        self.typestore = transport.typestore
        self._restart_ns = max(MIN_RESTART_NS, config.tolerance_ns + config.lateness_ns)
        self._lock = threading.Lock()
        self._labels: dict[str, list[str]] = {}
        self._past: dict[str, MethodCounts] = {m: MethodCounts() for m in config.methods}
        self._past_queue_drops = 0
        self._past_latencies: list[float] = []
        self._newest_gt: int | None = None
        self._info_topics = {config.left_info_topic, config.right_info_topic} - {None}
        self._infos: dict[str, object] = {}
        self._static_transforms: list[object] = []
        self.published = 0
        """Scores arrays published so far."""
        self.source_id = f"dispeval-live@{os.getpid()}-{secrets.token_hex(3)}"
        """This evaluator in delivery records (unique per run)."""
        self.publish_errors = 0
        self.restarts = 0
        self.scores_writer = transport.writer(SCORES_TOPIC, DIAGNOSTIC_ARRAY, RESULTS)
        self.vector_writers = {
            method: transport.writer(vector_topic(method), FLOAT64_MULTI_ARRAY, VECTOR_QOS)
            for method in config.methods
        }
        self._outbox: deque[FrameResult] = deque()
        self._outbox_ready = threading.Condition()
        self._outbox_closed = False
        self._publisher = threading.Thread(
            target=self._publish_loop, name="dispeval-publish", daemon=True
        )
        self._publisher.start()
        self.live = self._new_live()
        self.thread = transport.reader_thread("evaluator", on_error)
        self.on_error = self.thread.on_error
        topics = dict(config.topics)
        if odometry is not None:  # the motion from the odometry, the mount maybe given
            topics.pop(TF_TOPIC, None)
            topics[odometry] = ODOMETRY_TYPE
            if mount is not None and config.tf_topic is None:
                topics.pop(TF_STATIC_TOPIC, None)
        self.readers = [
            transport.reader(topic, msgtype, subscription_qos(topic, msgtype, subscription))
            for topic, msgtype in topics.items()
        ]
        for reader in self.readers:
            self.thread.add(reader, self._push)

    def _new_live(self) -> LiveEvaluator:
        live = LiveEvaluator(self.config, self._on_result, queue_size=self.queue_size, workers=2)
        if live.core.motion is not None:
            live.core.motion.mount = self.mount
        return live

    def start(self) -> None:
        """Start taking messages."""
        self.thread.start()

    # -- input (the reader thread) -----------------------------------------------------------

    def _push(self, received: Received) -> None:
        if received.topic == self.odometry:
            motion = self.live.core.motion
            if motion is not None:
                motion.push_odometry(received.topic, received.msg)
            return
        if received.topic == self.config.gt_topic:
            stamp = stamp_ns(received.msg.header)
            newest = self._newest_gt
            if newest is not None and stamp < newest - self._restart_ns:
                self._restart()
                newest = None
            self._newest_gt = stamp if newest is None else max(newest, stamp)
        elif received.topic in self._info_topics:
            self._infos[received.topic] = received.msg
        elif received.topic == TF_STATIC_TOPIC:  # LiDAR extrinsic or camera mount
            self._static_transforms.append(received.msg)
        self.live.push(received.topic, received.msg)

    def _restart(self) -> None:
        """Score what the old pass holds and start a fresh join."""
        old = self.live
        old.stop(flush=True)
        with self._lock:
            for method, counts in old.counts().items():
                past = self._past[method]
                past.matched += counts.matched
                past.unmatched += counts.unmatched
                past.dropped += counts.dropped
                past.failed += counts.failed
            self._past_queue_drops += old.stats.queue_drops
            self._past_latencies.extend(old.stats.latencies)
            self.live = self._new_live()
            self.restarts += 1
        for topic, msg in self._infos.items():  # the camera is the same in the new pass
            self.live.push(topic, msg)
        for msg in self._static_transforms:  # and so are the static transforms
            self.live.push(TF_STATIC_TOPIC, msg)

    # -- output (the scoring thread) ---------------------------------------------------------

    def _on_result(self, result: FrameResult) -> None:
        """Hand a result to the publishing thread, so scoring goes on with the next frame."""
        with self._outbox_ready:
            self._outbox.append(result)
            self._outbox_ready.notify()

    def _publish_loop(self) -> None:
        while True:
            with self._outbox_ready:
                while not self._outbox and not self._outbox_closed:
                    self._outbox_ready.wait()
                if not self._outbox:
                    return
                result = self._outbox.popleft()
            try:
                self.publish(result)
            except Exception as error:  # never let a transport problem end publishing
                self.publish_errors += 1
                if self.publish_errors == 1 or self.publish_errors % 100 == 0:
                    self.on_error(f"publishing the scores of {result.stamp} failed: {error}")
                continue
            if self.on_result is not None:
                self.on_result(result)

    def records(self, result: FrameResult) -> list[StatusRecord]:
        """The statuses of one frame: one per scored method, one ERROR per problem."""
        records = result_statuses(result, self.config.methods, self.alarms)
        records.extend(problem_statuses(result, self.config.methods, self.config.gt_topic))
        return records

    def publish(self, result: FrameResult) -> None:
        """Publish one frame's scores (with the delivery record) and every method's vector."""
        records = self.records(result)
        records.append(delivery_record(self.source_id, self.published + 1, self.counts()))
        self.scores_writer.publish(diagnostic_array(self.typestore, result.stamp, records))
        for method, scores in result.scores.items():
            labels = self._labels.get(method)
            if labels is None:
                labels = vector_labels(scores.criteria, scores.measures)
                self._labels[method] = labels
            self.vector_writers[method].publish(
                vector_message(self.typestore, labels, score_vector(scores, labels))
            )
        self.published += 1

    # -- state and shutdown ------------------------------------------------------------------

    def counts(self) -> dict[str, MethodCounts]:
        """Matched / unmatched / dropped / failed per method, over every pass."""
        with self._lock:
            current = self.live.counts()
            return {
                method: MethodCounts(
                    past.matched + current[method].matched,
                    past.unmatched + current[method].unmatched,
                    past.dropped + current[method].dropped,
                    past.failed + current[method].failed,
                )
                for method, past in self._past.items()
            }

    def final_delivery(self) -> Delivery:
        """The final delivery record, for a summarizer in this process (after :meth:`stop`)."""
        return Delivery(self.source_id, self.published, final=True, counts=self.counts())

    @property
    def queue_drops(self) -> int:
        """Frames dropped because scoring could not keep up."""
        return self._past_queue_drops + self.live.stats.queue_drops

    def latencies(self) -> list[float]:
        """Seconds from a frame's last message to its scores, every pass."""
        return [*self._past_latencies, *self.live.stats.latencies]

    def received(self) -> int:
        """Messages taken from DDS so far."""
        return self.thread.received

    def stop(self, flush: bool = True) -> None:
        """Stop listening; with ``flush``, score and publish everything that arrived."""
        self.thread.stop(drain=flush)
        self.live.stop(flush=flush)
        with self._outbox_ready:
            if not flush:
                self._outbox.clear()
            self._outbox_closed = True
            self._outbox_ready.notify_all()
        self._publisher.join()
