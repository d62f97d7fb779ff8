"""The ``evaluator`` node (``dispeval_evaluator``): score stereo methods live, publish the scores.

A thin adapter over :class:`~dispeval_ros.stream.runner.LiveEvaluator`: subscription callbacks
only push messages (joining by header stamp, never scoring); the scoring thread publishes each
frame's results:

- ``/dispeval/scores`` (``diagnostic_msgs/DiagnosticArray``, stamp = the ground-truth frame's):
  one status per method (name = method, hardware_id = its topic, every ``criterion/measure``
  plus the exact sums, level from the alarms), an ERROR status per frame problem, and the
  delivery record (:mod:`dispeval_ros.stream.delivery`: this evaluator's id, the array's index
  and its per-method counts) from which a summarizer stores the counts and counts what it
  lost; a last array with the final delivery record is sent at shutdown;
- ``/dispeval/NAME/vector`` (``std_msgs/Float64MultiArray``) with its labels latched on
  ``/dispeval/NAME/vector_labels`` (see :mod:`dispeval_ros.ros.convert`);
- with ``error_images``: ``/dispeval/NAME/error`` (32FC1) and ``/dispeval/NAME/error_color``
  (rgb8).

With the ``bag`` parameter a thread replays the recording into the same evaluator instead of
subscribing, each message arriving at its log time (delays as ``dispeval bag`` measures them).
Live, a message arrives when received: on the wall clock, or on the node's clock with
``use_sim_time`` (messages before the first /clock are refused, with a warning).

On SIGINT / SIGTERM (or the end of a replay) every frame already joined is scored
and published before the node exits, and the per-method counts are logged.
"""

from __future__ import annotations

import functools
import os
import secrets
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import ROSClock
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from sensor_msgs.msg import CameraInfo, Image, PointCloud2
from std_msgs.msg import Float64MultiArray, String
from stereo_msgs.msg import DisparityImage

from dispeval_ros.errors import ConfigurationError, DispevalError, InputError
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.ros import convert, static_tf
from dispeval_ros.ros.lifecycle import run_node
from dispeval_ros.ros.param_table import EVALUATOR_PARAMETERS
from dispeval_ros.ros.params import declare_parameters, evaluator_options
from dispeval_ros.stream.alarms import AlarmThresholds
from dispeval_ros.stream.config import TF_TOPIC
from dispeval_ros.stream.core import (
    CAMERA_INFO_TYPE,
    DISPARITY_TYPE,
    IMAGE_TYPE,
    POINT_CLOUD_TYPE,
    TF_STATIC_TOPIC,
    TF_TYPE,
    FrameResult,
    MethodCounts,
)
from dispeval_ros.stream.delivery import delivery_record
from dispeval_ros.stream.images import colour_error
from dispeval_ros.stream.replay import replay
from dispeval_ros.stream.runner import LiveEvaluator
from dispeval_ros.stream.topics import (
    ERROR_COLOR_LEAF,
    ERROR_LEAF,
    SCORES_TOPIC,
    VECTOR_LABELS_LEAF,
    VECTOR_LEAF,
    method_topic,
)
from dispeval_ros.stream.vectors import (
    problem_statuses,
    result_statuses,
    score_vector,
    vector_labels,
)

NODE_NAME = "dispeval_evaluator"
SCORES_DEPTH = 1000
"""Scores arrays kept for a slow (reliable) subscriber: about a minute at 15 Hz, a few MB."""
SCORES_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=SCORES_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
RESULTS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
LATCHED_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
LOG_PERIOD = 5.0
"""Seconds between repeated log lines of the same kind (frame problems, publish failures)."""
ACK_TIMEOUT = 2.0
"""Seconds to wait at shutdown for subscribers to acknowledge the last scores."""

_MESSAGE_CLASSES = {
    IMAGE_TYPE: Image,
    DISPARITY_TYPE: DisparityImage,
    CAMERA_INFO_TYPE: CameraInfo,
    POINT_CLOUD_TYPE: PointCloud2,
}


class EvaluatorNode(Node):
    """Subscriptions (or a bag replay) → :class:`LiveEvaluator` → result publishers."""

    def __init__(self, *, stop: threading.Event | None = None, **node_options: Any) -> None:
        super().__init__(NODE_NAME, **node_options)
        self.exit_code = 0
        self._stop = stop if stop is not None else threading.Event()
        values = declare_parameters(self, EVALUATOR_PARAMETERS)
        self.options = evaluator_options(values)
        self.config = self.options.core
        self._alarm_items = {name: tuple(values[name]) for name in ("alarm_warn", "alarm_error")}
        self._alarms: AlarmThresholds = self.options.alarms
        self._gt_frame_id = ""
        self._labels: dict[str, list[str]] = {}
        self._finished = False
        self.source_id = f"{self.get_fully_qualified_name()}@{os.getpid()}-{secrets.token_hex(3)}"
        """This evaluator in delivery records (unique per run, so a restart is a new source)."""
        self._publish_lock = threading.Lock()
        self.published = 0
        """Scores arrays published so far."""
        self.publish_failures = 0
        """Scored frames whose scores could not be published (counted, logged at shutdown)."""
        self._last_stamp = 0
        if self.options.bag is not None:
            _check_bag(self.options.bag, list(self.config.topics))

        methods = list(self.config.methods)
        self._scores_pub = self.create_publisher(DiagnosticArray, SCORES_TOPIC, SCORES_QOS)
        self._vector_pubs = {
            m: self.create_publisher(Float64MultiArray, method_topic(m, VECTOR_LEAF), RESULTS_QOS)
            for m in methods
        }
        self._label_pubs = {
            m: self.create_publisher(String, method_topic(m, VECTOR_LABELS_LEAF), LATCHED_QOS)
            for m in methods
        }
        self._error_pubs: dict[str, Any] = {}
        self._colour_pubs: dict[str, Any] = {}
        if self.options.error_images:
            for m in methods:
                self._error_pubs[m] = self.create_publisher(
                    Image, method_topic(m, ERROR_LEAF), RESULTS_QOS
                )
                self._colour_pubs[m] = self.create_publisher(
                    Image, method_topic(m, ERROR_COLOR_LEAF), RESULTS_QOS
                )

        self._live = LiveEvaluator(
            self.config,
            self._on_result,
            queue_size=self.options.queue_size,
            max_buffered=self.options.max_buffered,
            error_images=self.options.error_images,
        )
        self._replay_thread: threading.Thread | None = None
        if self.options.bag is not None:
            self._replay_thread = threading.Thread(
                target=self._replay, name="dispeval-replay", daemon=True
            )
            self._replay_thread.start()
        else:
            self._tf_listener = self._static_transforms()
            self._motion_subs = self._motion_subscriptions()
            for topic, type_name in self.config.topics.items():
                if topic == self.config.tf_topic or type_name == TF_TYPE:
                    continue  # subscribed by _static_transforms and _motion_subscriptions
                self.create_subscription(
                    _MESSAGE_CLASSES[type_name],
                    topic,
                    self._subscriber(topic),
                    qos_profile_sensor_data,
                )
        self.add_on_set_parameters_callback(self._on_set_parameters)
        source = f"bag {self.options.bag}" if self.options.bag is not None else "live topics"
        self.get_logger().info(
            f"evaluating {', '.join(f'{m} ({t})' for m, t in self.config.methods.items())} "
            f"against {self.config.gt_topic} from {source}"
        )

    # -- input ------------------------------------------------------------------------------

    def _static_transforms(self) -> Any:
        """Point-cloud GT without lidar_extrinsic: tf2_ros's buffer, else raw /tf_static."""
        topic = self.config.tf_topic
        if topic is None:
            return None
        found = static_tf.tf2_lookup(self)
        if found is not None:
            self._live.core.extrinsic_lookup, listener = found
            return listener
        return self.create_subscription(
            static_tf.tf_message_class(), topic, self._subscriber(topic), static_tf.static_tf_qos()
        )

    def _motion_subscriptions(self) -> list[Any]:
        """With ``egomotion``: /tf and /tf_static (tf2_msgs), or the odometry topic.

        The odometry is read instead of /tf and ``camera_mount`` instead of /tf_static, as
        ``dispeval live`` reads them. Each message goes to the core's motion source as it
        comes (no receipt time needed).
        """
        motion = self._live.core.motion
        if motion is None:
            return []
        options = self.options
        motion.mount = static_tf.mount_matrix(options.camera_mount)
        subscriptions = []
        transforms = [(TF_TOPIC, static_tf.dynamic_tf_qos())]
        if options.odometry_topic is not None:
            transforms = []
        if options.camera_mount is None:
            transforms.append((TF_STATIC_TOPIC, static_tf.static_tf_qos()))
        tf_class = static_tf.tf_message_class(options.odometry_topic is None, egomotion=True)
        if tf_class is not None:
            for topic, qos in transforms:
                callback = functools.partial(motion.push, topic)
                subscriptions.append(self.create_subscription(tf_class, topic, callback, qos))
        if options.odometry_topic is not None:
            topic = options.odometry_topic
            subscriptions.append(
                self.create_subscription(
                    static_tf.odometry_class(),
                    topic,
                    functools.partial(motion.push_odometry, topic),
                    static_tf.dynamic_tf_qos(reliable=False),
                )
            )
        return subscriptions

    def _subscriber(self, topic: str) -> Callable[[Any], None]:
        def callback(msg: Any) -> None:
            try:
                received = self._receipt(topic)
            except InputError as error:
                self.get_logger().warning(str(error), throttle_duration_sec=LOG_PERIOD)
                return
            self._push(topic, msg, received)

        return callback

    def _receipt(self, topic: str) -> int | None:
        """The receipt time on sim time (``use_sim_time``: the node's clock, i.e. /clock).

        None on system time: the live evaluator's monotonic clock shifted to the wall clock.
        Raises before the first /clock for a message that is joined (a delay or wait against
        time 0 would be meaningless); CameraInfo and static transforms need no receipt.
        """
        clock = self.get_clock()
        if not isinstance(clock, ROSClock) or not clock.ros_time_is_active:
            return None
        now = int(clock.now().nanoseconds)
        config = self.config
        if now <= 0 and topic not in (
            config.left_info_topic,
            config.right_info_topic,
            config.tf_topic,
        ):
            raise InputError(
                f"use_sim_time is set but no /clock was received yet: the message on {topic} "
                "has no receipt time to measure its delay against (ignored)"
            )
        return now

    def _push(self, topic: str, msg: Any, received: int | None = None) -> None:
        """Hand one message to the live evaluator (never blocks on scoring).

        ``received`` (ns, the stamps' clock): its arrival (a bag's log time, sim-time receipt).
        """
        try:
            if topic == self.config.gt_topic:
                self._gt_frame_id = str(msg.header.frame_id)
            self._live.push(topic, msg, received)
        except DispevalError as error:
            self.get_logger().warning(
                f"ignoring a message on {topic}: {error}", throttle_duration_sec=LOG_PERIOD
            )

    def _replay(self) -> None:
        """The bag thread: replay (again and again with ``bag_loop``), then stop the node."""
        options = self.options
        assert options.bag is not None
        try:
            if not self._wait_for_subscribers(options.bag_wait_subscribers):
                return
            offset = 0
            passes = 0
            while not self._stop.is_set():
                span, pushed = self._replay_once(options.bag, offset)
                passes += 1
                if not options.bag_loop or pushed == 0 or span is None:
                    break
                # The next pass continues in stamp and log time after this one.
                offset += span + self.config.tolerance_ns + self.config.lateness_ns + 1
            self.get_logger().info(f"replayed {options.bag} ({passes} pass(es))")
        except DispevalError as error:
            self.get_logger().error(f"cannot replay {options.bag}: {error}")
            self.exit_code = 2
        except Exception as error:  # keep the node alive to finish what was scored
            self.get_logger().error(f"replay of {options.bag} failed: {error!r}")
            self.exit_code = 1
        if self.exit_code or (options.bag_exit and not self._stop.is_set()):
            self._stop.set()  # the main loop ends, finish() scores and publishes the rest
        elif not self._stop.is_set():
            self._live.stop(flush=True)  # score the tail now; the node stays up (bag_exit false)

    def _wait_for_subscribers(self, wanted: int) -> bool:
        """Wait until ``wanted`` subscribers matched /dispeval/scores; False if stopped first."""
        logged = 0.0
        while wanted and self._scores_pub.get_subscription_count() < wanted:
            now = time.monotonic()
            if now - logged > LOG_PERIOD:
                self.get_logger().info(
                    f"waiting for {wanted} subscriber(s) on {SCORES_TOPIC} before replaying"
                )
                logged = now
            if self._stop.wait(0.1):
                return False
        return not self._stop.is_set()

    def _replay_once(self, bag: Path, offset: int) -> tuple[int | None, int]:
        """One pass over the bag, stamps and log times moved by ``offset`` ns.

        Each message arrives at its log time (as in ``dispeval bag``, so the delays are the
        recording's). Returns the pass's span (the longer of its stamps' and log times'; None
        if no message had a stamp) and the count.
        """
        stamps: list[int] = []
        logs: list[int] = []
        as_fast_as_possible = self.options.bag_rate is None

        def push(topic: str, msg: Any, log_time: int) -> None:
            if self.config.topics.get(topic) == TF_TYPE:  # no header: each transform's stamp
                self._push(
                    topic, _ShiftedTransforms(msg, offset) if offset else msg, log_time + offset
                )
                return
            for seen, value in ((stamps, stamp_ns(msg.header)), (logs, log_time)):
                if not seen:
                    seen.extend((value, value))
                seen[0], seen[1] = min(seen[0], value), max(seen[1], value)
            self._push(topic, _Shifted(msg, offset) if offset else msg, log_time + offset)
            if as_fast_as_possible:
                self._live.wait_idle()  # lossless: never more than one frame ahead of scoring

        pushed = replay(
            bag, list(self.config.topics), push, rate=self.options.bag_rate, stop=self._stop
        )
        if not stamps:
            return None, pushed
        return max(stamps[1] - stamps[0], logs[1] - logs[0]), pushed

    # -- output (the scoring thread) --------------------------------------------------------

    def _on_result(self, result: FrameResult) -> None:
        """Publish one scored frame; never raises (it would stop the scoring thread)."""
        try:
            self._publish(result)
        except Exception as error:
            self.publish_failures += 1
            self.get_logger().error(
                f"cannot publish the scores of the frame at {result.stamp} ns: {error!r}",
                throttle_duration_sec=LOG_PERIOD,
            )

    def _publish(self, result: FrameResult) -> None:
        alarms = self._alarms
        frame_id = self._gt_frame_id
        records = result_statuses(result, self.config.methods, alarms)
        for _, problem in result.problems:
            self.get_logger().warning(problem, throttle_duration_sec=LOG_PERIOD)
        records.extend(problem_statuses(result, self.config.methods, self.config.gt_topic))
        if records:
            with self._publish_lock:
                index = self.published + 1
                records.append(delivery_record(self.source_id, index, self._live.counts()))
                self._scores_pub.publish(convert.diagnostic_array(result.stamp, records, frame_id))
                self.published = index
                self._last_stamp = max(self._last_stamp, result.stamp)
        for method, scores in result.scores.items():
            labels = vector_labels(scores.criteria, scores.measures)
            if labels != self._labels.get(method):
                self._labels[method] = labels
                self._label_pubs[method].publish(convert.labels_msg(labels))
            self._vector_pubs[method].publish(convert.vector_msg(score_vector(scores, labels)))
        if result.partition is None:
            return
        for method, error in result.errors.items():
            error_pub, colour_pub = self._error_pubs.get(method), self._colour_pubs.get(method)
            if error_pub is not None and error_pub.get_subscription_count() > 0:
                error_pub.publish(convert.image_msg(error, result.stamp, frame_id, "32FC1"))
            if colour_pub is not None and colour_pub.get_subscription_count() > 0:
                rgb = colour_error(error, result.partition)
                colour_pub.publish(convert.image_msg(rgb, result.stamp, frame_id, "rgb8"))

    # -- parameters -------------------------------------------------------------------------

    def _on_set_parameters(self, parameters: Sequence[Any]) -> SetParametersResult:
        """Alarm thresholds may change at run time; the new ones apply from the next frame."""
        items = dict(self._alarm_items)
        for parameter in parameters:
            if parameter.name in items:
                items[parameter.name] = tuple(parameter.value or ())
        if items == self._alarm_items:
            return SetParametersResult(successful=True)
        try:
            alarms = AlarmThresholds.parse(items["alarm_warn"], items["alarm_error"])
        except ConfigurationError as error:
            return SetParametersResult(successful=False, reason=str(error))
        self._alarm_items = items
        self._alarms = alarms
        return SetParametersResult(successful=True)

    # -- shutdown ---------------------------------------------------------------------------

    def finish(self, executor: Any = None) -> None:
        """Stop input, score and publish every joined frame, log the counts (idempotent).

        Call it before :meth:`destroy_node`: the last scores need the publishers.
        """
        if self._finished:
            return
        self._finished = True
        self._stop.set()
        if self._replay_thread is not None:
            self._replay_thread.join(timeout=30.0)
        self._live.stop(flush=True)
        acknowledged = self._publish_final_counts()
        logger = self.get_logger()
        stats = self._live.stats
        logger.info(
            f"scored {stats.results} frame(s); {stats.queue_drops} dropped because scoring "
            f"fell behind; published {self.published} scores array(s)"
        )
        if self.publish_failures:
            logger.warning(f"{self.publish_failures} scored frame(s) could not be published")
        if not acknowledged:
            logger.warning(
                f"not every subscriber of {SCORES_TOPIC} acknowledged the last scores within "
                f"{ACK_TIMEOUT:g} s: they may not have received them"
            )
        motion = self._live.core.motion
        for line in [] if motion is None else motion.problems():
            logger.warning(line)
        for method, counts in self._live.counts().items():
            logger.info(
                f"{method}: matched {counts.matched}, unmatched {counts.unmatched}, "
                f"dropped {counts.dropped}, failed {counts.failed}"
            )

    def _publish_final_counts(self) -> bool:
        """Send the final delivery record, then wait for acknowledgements; False if none came."""
        try:
            with self._publish_lock:
                record = delivery_record(
                    self.source_id, self.published, self._live.counts(), final=True
                )
                self._scores_pub.publish(
                    convert.diagnostic_array(self._last_stamp, [record], self._gt_frame_id)
                )
            return bool(self._scores_pub.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT)))
        except Exception as error:  # e.g. the context is already shut down
            self.get_logger().warning(f"cannot publish the final counts: {error!r}")
            return False

    @property
    def frames_scored(self) -> int:
        """How many joined frames have been scored (and published) so far."""
        return self._live.stats.results

    def counts(self) -> dict[str, MethodCounts]:
        """Per method: matched (scored), unmatched, dropped and failed so far."""
        return self._live.counts()


class _Shifted:
    """A message whose header stamp is moved by ``offset`` ns (each bag loop continues in time)."""

    def __init__(self, msg: Any, offset: int) -> None:
        self._msg = msg
        sec, nanosec = divmod(stamp_ns(msg.header) + offset, 1_000_000_000)
        self.header = SimpleNamespace(
            stamp=SimpleNamespace(sec=sec, nanosec=nanosec),
            frame_id=getattr(msg.header, "frame_id", ""),
        )

    def __getattr__(self, name: str) -> Any:
        return getattr(self._msg, name)


class _ShiftedTransforms:
    """A ``TFMessage`` whose transforms' stamps are moved by ``offset`` ns, as the frames are.

    A later pass of ``bag_loop`` then finds the camera's motion at its shifted stamps.
    """

    def __init__(self, msg: Any, offset: int) -> None:
        self.transforms = [_Shifted(stamped, offset) for stamped in msg.transforms]


def _check_bag(path: Path, topics: Sequence[str]) -> None:
    """Fail at start-up (one line) when the bag cannot be read or lacks a topic."""
    with BagSource(path) as source:
        missing = [topic for topic in topics if topic not in source.topics]
    if missing:
        raise InputError(
            f"{path}: no topic {', '.join(missing)} in the bag; it has {', '.join(source.topics)}"
        )


def main(args: Sequence[str] | None = None) -> int:
    """``ros2 run dispeval_ros evaluator``: run the node until SIGINT / SIGTERM."""
    return run_node(lambda stop: EvaluatorNode(stop=stop), NODE_NAME, args)


if __name__ == "__main__":
    raise SystemExit(main())
