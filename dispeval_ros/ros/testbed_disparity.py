"""The test-bed's disparity node: stereo_image_proc's interface, OpenCV inside, over rclpy.

It subscribes ``left/image_rect``, ``right/image_rect`` (mono8) and ``left/camera_info``,
``right/camera_info`` (sensor-data QoS, as REP 2003 and the real node), joins them by exact
stamp and publishes ``disparity`` (``stereo_msgs/DisparityImage``) with the parameters the real
node declares (names, ranges, defaults: :mod:`dispeval_ros.testbed.node_parameters`), each
settable at run time through the standard parameter services. What it computes is
:class:`~dispeval_ros.testbed.disparity_node.DisparityNodeModel`'s: this module only moves
messages. ``ros2 run dispeval_ros testbed_disparity`` (node name ``disparity_node``).
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Sequence
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import CameraInfo, Image
from stereo_msgs.msg import DisparityImage

from dispeval_ros.errors import DispevalError
from dispeval_ros.io.messages import image_from_msg, rectified_camera_from_info, stamp_ns
from dispeval_ros.ros import convert
from dispeval_ros.ros.lifecycle import run_node
from dispeval_ros.ros.param_table import DOUBLE, INTEGER, Param
from dispeval_ros.ros.params import declare_parameters
from dispeval_ros.testbed.disparity_node import (
    INPUTS,
    OUTPUT,
    DisparityNodeModel,
    ExactTimeSync,
    node_defaults,
)
from dispeval_ros.testbed.node_parameters import (
    ALGORITHM_PARAMETER,
    DEFAULT_NODE_NAME,
    PARAMETERS,
)


def parameter_rows() -> tuple[Param, ...]:
    """The node's parameters as declarable rows (descriptors with the node's ranges)."""
    rows = [
        Param(
            ALGORITHM_PARAMETER,
            INTEGER,
            node_defaults()[ALGORITHM_PARAMETER],
            "Stereo algorithm: Block Matching (0) or Semi-Global Block Matching (1)",
            read_only=False,
            low=0,
            high=1,
        )
    ]
    for parameter in PARAMETERS.values():
        rows.append(
            Param(
                parameter.name,
                DOUBLE if parameter.floating else INTEGER,
                float(parameter.default) if parameter.floating else parameter.default,
                f"OpenCV {parameter.field} ({', '.join(parameter.families)}){parameter.note}",
                read_only=False,
                low=parameter.low,
                high=parameter.high,
                step=parameter.step,
            )
        )
    return tuple(rows)


class TestbedDisparityNode(Node):
    """stereo_image_proc's disparity node, as far as ``dispeval tune --node`` can tell."""

    def __init__(self, name: str = DEFAULT_NODE_NAME, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.model = DisparityNodeModel()
        self._lock = threading.Lock()
        self.add_on_set_parameters_callback(self._on_set)
        self.model.update(declare_parameters(self, parameter_rows()))
        self.queue_size = 5
        self._sync = ExactTimeSync(INPUTS, self.queue_size)
        self.frames_published = 0
        self.frames_failed = 0
        for topic in INPUTS:
            kind = Image if topic.endswith("image_rect") else CameraInfo
            receive = functools.partial(self._on_input, topic)
            self.create_subscription(kind, topic, receive, qos_profile_sensor_data)
        self._publisher = self.create_publisher(DisparityImage, OUTPUT, 1)

    def finish(self, executor: Any = None) -> None:
        """Nothing kept to flush: say what was published (``run_node`` calls this last)."""
        self.get_logger().info(
            f"published {self.frames_published} disparity map(s), {self.frames_failed} failed, "
            f"{self._sync.dropped} incomplete input set(s) dropped"
        )

    def _on_set(self, parameters: Sequence[Any]) -> SetParametersResult:
        """Take a change of the matcher's parameters, or refuse it with the model's reason."""
        changes = {p.name: p.value for p in parameters if p.name in self.model.values}
        try:
            with self._lock:
                self.model.update(changes)
        except DispevalError as error:
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _on_input(self, topic: str, msg: Any) -> None:
        members = self._sync.add(topic, stamp_ns(msg.header), msg)
        if members is None or self._publisher.get_subscription_count() == 0:
            return  # as the real node: nothing computed while nobody listens
        try:
            self._publisher.publish(self._disparity(members))
            self.frames_published += 1
        except DispevalError as error:
            self.frames_failed += 1
            self.get_logger().warning(f"cannot compute the disparity: {error}")

    def _disparity(self, members: dict[Any, Any]) -> DisparityImage:
        left_info, right_info = members[INPUTS[1]], members[INPUTS[3]]
        left_view = rectified_camera_from_info(left_info, INPUTS[1])
        right_view = rectified_camera_from_info(right_info, INPUTS[3])
        fx_right = float(right_view.projection[0, 0])
        baseline = -float(right_view.projection[0, 3]) / fx_right
        doffs = float(left_view.projection[0, 2] - right_view.projection[0, 2])
        left = image_from_msg(members[INPUTS[0]], INPUTS[0]).array
        right = image_from_msg(members[INPUTS[2]], INPUTS[2]).array
        with self._lock:
            output = self.model.process(left, right, fx_right, baseline, doffs)
        header = left_info.header
        image = convert.image_msg(output.disparity, stamp_ns(header), header.frame_id, "32FC1")
        message = DisparityImage(
            header=header,
            image=image,
            f=output.f,
            t=output.t,
            min_disparity=output.min_disparity,
            max_disparity=output.max_disparity,
            delta_d=output.delta_d,
        )
        x, y, width, height = output.valid_window
        window = message.valid_window
        window.x_offset, window.y_offset = x % 2**32, y % 2**32  # unsigned, as the real node's
        window.width, window.height = width % 2**32, height % 2**32
        return message


def main(args: Sequence[str] | None = None) -> int:
    """``ros2 run dispeval_ros testbed_disparity``."""
    return run_node(lambda stop: TestbedDisparityNode(), DEFAULT_NODE_NAME, args)


if __name__ == "__main__":  # python -m dispeval_ros.ros.testbed_disparity [--ros-args ...]
    raise SystemExit(main())
