"""``dispeval tune --node NAME``: sweep a running ROS 2 stereo node through its parameter services.

For each configuration the node's parameters are set (atomically, checked with GetParameters:
:class:`~dispeval_ros.ros.parameter_client.RemoteParameters`), then every scene frame is sent
to its inputs (``left/image_rect``, ``right/image_rect`` mono8 and the CameraInfo pair, the
stereo_image_proc interface) with a stamp of its own per (configuration, frame), and its
``disparity`` of that stamp is awaited (``timeout`` s; a frame it drops is a counted miss, not a
hang). Each map is read as the message defines it (:func:`~dispeval_ros.io.messages.
disparity_from_msg`: valid inside ``[min_disparity, max_disparity]``) and scored with the
evaluator and reference the offline sweep uses, one unit per configuration into the same kind
of results database (:mod:`dispeval_ros.stream.tuning`), so a resumed run skips the units done.
The node's original parameters are put back at the end, on Ctrl-C and on errors.

The CameraInfo pair carries the scene's ``f`` and baseline with equal principal points: the
node then publishes the matcher's ``x_l − x_r`` itself (stereo_image_proc subtracts
``cx_l − cx_r``, which would move the values out of the search range it declares); the depth
measures take the scene's ``doffs`` from the reference, as offline.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import CameraInfo, Image
from stereo_msgs.msg import DisparityImage

from dispeval_ros.core import Evaluator
from dispeval_ros.core.camera import Camera
from dispeval_ros.core.records import FrameScores, MatchCounts
from dispeval_ros.errors import ConfigurationError, DispevalError
from dispeval_ros.io.messages import camera_from_infos, disparity_from_msg, stamp_ns
from dispeval_ros.io.store import ResultsStore, prepare_unit
from dispeval_ros.ros import convert
from dispeval_ros.ros.parameter_client import RemoteParameters
from dispeval_ros.stream.tuning import NODE_TIMEOUT, SceneFrame, SweepReport, TuneUnit, start_sweep
from dispeval_ros.testbed.disparity_node import INPUTS, OUTPUT
from dispeval_ros.testbed.node_parameters import Configuration, ros_parameters

NOMINAL_CAMERA = Camera(1.0, 1.0)
"""Sent when a scene has no calibration (the node needs a CameraInfo pair; no depth scored)."""
STAMP_STEP_NS = 1000
"""Between the stamps sent (unique per configuration and frame, increasing)."""


def split_name(node: str, namespace: str | None) -> tuple[str, str]:
    """The node's fully qualified name and the namespace of its topics (default: its own)."""
    target = node if node.startswith("/") else f"/{node}"
    own = target.rsplit("/", 1)[0] or "/"
    topics = own if namespace is None else namespace
    if not topics.startswith("/"):
        topics = f"/{topics}"
    return target, topics.rstrip("/")


def camera_info(camera: Camera, frame: SceneFrame, stamp: int, right: bool) -> CameraInfo:
    """The rectified CameraInfo of one side: ``P = [f 0 cx −f·B; 0 f cy 0; 0 0 1 0]`` (right)."""
    height, width = frame.left.shape[:2]
    f, cx, cy = float(camera.f), width / 2.0 - 0.5, height / 2.0 - 0.5
    tx = -f * float(camera.baseline) if right else 0.0
    return CameraInfo(
        header=convert.header_msg(stamp, "stereo_right" if right else "stereo_left"),
        height=height,
        width=width,
        distortion_model="plumb_bob",
        d=[0.0] * 5,
        k=[f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0],
        r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p=[f, 0.0, cx, tx, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
    )


class NodeSweep:
    """A connection to one node: its parameters, its inputs and its output (a context manager).

    Opening checks the node is there, has every parameter of ``family``, takes the
    configuration ``start`` and answers a frame with it, before anything is written; closing
    restores its parameters (unless it stopped answering) and shuts the connection down.
    """

    def __init__(
        self,
        node: str,
        family: str,
        first: SceneFrame,
        start: Configuration,
        namespace: str | None = None,
        timeout: float = NODE_TIMEOUT,
    ) -> None:
        self.target, self.namespace = split_name(node, namespace)
        self.family = family
        self.timeout = timeout
        self._first = first
        self._start = start
        self._stamp = time.time_ns() // STAMP_STEP_NS * STAMP_STEP_NS
        self._outputs: dict[int, Any] = {}
        self._wanted: set[int] = set()
        self.context = Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.helper: Any = None
        self.remote: RemoteParameters | None = None

    def __enter__(self) -> NodeSweep:
        try:
            self._open()
        except BaseException:
            self._shutdown()
            raise
        return self

    def __exit__(self, kind: Any, error: Any, trace: Any) -> None:
        try:
            if self.remote is not None:
                self.remote.restore()
        except DispevalError:
            if kind is None:  # else the run's own error is the line to show
                raise
        finally:
            self._shutdown()

    def _open(self) -> None:
        self.helper = rclpy.create_node("dispeval_tune", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.helper)
        self.remote = RemoteParameters(self.helper, self.target, self.executor)
        self.remote.wait()
        self.remote.get(ros_parameters(self.family, {}))  # one line if it lacks one
        topic = lambda name: f"{self.namespace}/{name}"  # noqa: E731
        self._publishers = {
            name: self.helper.create_publisher(
                Image if name.endswith("image_rect") else CameraInfo,
                topic(name),
                qos_profile_sensor_data,
            )
            for name in INPUTS
        }
        self.output = topic(OUTPUT)
        self.helper.create_subscription(
            DisparityImage, self.output, self._on_output, QoSProfile(depth=10)
        )
        connected = self._spin_until(
            lambda: (
                all(p.get_subscription_count() for p in self._publishers.values())
                and self.helper.count_publishers(self.output) > 0
            ),
            self.timeout,
        )
        if not connected:
            raise ConfigurationError(
                f"node {self.target} does not take {', '.join(map(topic, INPUTS))} or publish "
                f"{self.output} (within {self.timeout:g} s); is --node-namespace right?"
            )
        self.remote.set(ros_parameters(self.family, self._start.values))  # what it will run
        for _ in range(3):  # until the node has seen this subscriber: it computes for listeners
            if self._send(self._first) is not None:
                return
        raise ConfigurationError(
            f"node {self.target} published nothing on {self.output} for 3 frames sent to its "
            f"inputs with configuration {self._start.name} (waited {self.timeout:g} s each)"
        )

    def _shutdown(self) -> None:
        try:
            if self.helper is not None:
                self.helper.destroy_node()
        finally:
            if self.context.ok():
                rclpy.shutdown(context=self.context)

    def _on_output(self, msg: Any) -> None:
        stamp = stamp_ns(msg.header)
        if stamp in self._wanted:
            self._outputs[stamp] = msg

    def _spin_until(self, condition: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=0.01)
        return True

    def _send(self, frame: SceneFrame) -> tuple[Any, Camera] | None:
        """Send one frame (a new stamp); the node's map and the camera sent, or None if dropped."""
        self._stamp += STAMP_STEP_NS
        stamp = self._stamp
        camera = frame.camera or NOMINAL_CAMERA
        left_info = camera_info(camera, frame, stamp, right=False)
        right_info = camera_info(camera, frame, stamp, right=True)
        messages = {
            "left/image_rect": convert.image_msg(frame.left, stamp, "stereo_left", "mono8"),
            "left/camera_info": left_info,
            "right/image_rect": convert.image_msg(frame.right, stamp, "stereo_right", "mono8"),
            "right/camera_info": right_info,
        }
        self._wanted.add(stamp)
        for name in INPUTS:
            self._publishers[name].publish(messages[name])
        arrived = self._spin_until(lambda: stamp in self._outputs, self.timeout)
        self._wanted.discard(stamp)
        msg = self._outputs.pop(stamp, None)
        if not arrived or msg is None:
            return None
        return msg, camera_from_infos(left_info, right_info)

    def _alive(self, configuration: str, done: int) -> None:
        """One line if the node stopped answering (its parameter service is the probe)."""
        assert self.remote is not None
        try:
            self.remote.get(["stereo_algorithm"])
        except ConfigurationError:
            self.remote = None  # nothing to restore on a node that is gone
            raise ConfigurationError(
                f"node {self.target} stopped answering during configuration {configuration}; "
                f"the {done} configuration unit(s) written are kept, continue with --resume"
            ) from None

    def run_unit(
        self,
        unit: TuneUnit,
        frames: Sequence[SceneFrame],
        evaluator: Evaluator,
        done: int,
    ) -> tuple[list[FrameScores], dict[str, MatchCounts]]:
        """Set each configuration of ``unit`` on the node, send the frames, score its maps."""
        assert self.remote is not None
        scored: list[FrameScores] = []
        counts: dict[str, MatchCounts] = {}
        for configuration in unit.configurations:
            try:
                self.remote.set(ros_parameters(self.family, configuration.values))
            except ConfigurationError as error:
                raise ConfigurationError(
                    f"{error}; the {done} configuration unit(s) written are kept, continue "
                    "with --resume"
                ) from None
            matched = dropped = 0
            for frame in frames:
                answer = self._send(frame)
                if answer is None:
                    dropped += 1
                    self._alive(configuration.name, done)
                    continue
                scored.append(self._score(answer, frame, configuration, unit, evaluator))
                matched += 1
            if dropped:  # let late maps of this configuration arrive (and be ignored)
                self._spin_until(lambda: False, min(self.timeout, 1.0))
            counts[configuration.name] = MatchCounts(matched, 0, dropped, 0)
        return scored, counts

    def _score(
        self,
        answer: tuple[Any, Camera],
        frame: SceneFrame,
        configuration: Configuration,
        unit: TuneUnit,
        evaluator: Evaluator,
    ) -> FrameScores:
        msg, camera = answer
        try:
            disparity = disparity_from_msg(msg, self.output)
            scores = evaluator.score(
                frame.reference, disparity.disparity, **disparity.scoring(camera)
            )
        except DispevalError as error:
            raise type(error)(
                f"node {self.target}, configuration {configuration.name}, frame {frame.frame}: "
                f"{error}"
            ) from None
        return FrameScores(unit.sequence, frame.stamp, configuration.name, scores)


def run_node_sweep(
    sweep: NodeSweep,
    store: ResultsStore,
    scenes: Sequence[Path],
    loaded: Mapping[int, list[SceneFrame]],
    configurations: Sequence[Configuration],
    evaluator: Evaluator,
    *,
    progress: Callable[[int, int, SweepReport], None] | None = None,
) -> SweepReport:
    """Score every configuration on the node, one unit per configuration (done units skipped)."""
    todo, report = start_sweep(store, scenes, loaded, configurations, 1)
    for unit in todo:
        frames = loaded[unit.scene]
        scored, counts = sweep.run_unit(unit, frames, evaluator, report.units_done)
        store.add_prepared(prepare_unit(unit.sequence, unit.name, scored, counts=counts))
        report.units_done += 1
        report.frames += len(scored)
        report.dropped += sum(count.dropped for count in counts.values())
        if progress is not None:
            progress(report.units_done, len(todo), report)
    return report
