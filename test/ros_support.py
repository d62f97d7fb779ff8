"""Importing ROS 2 modules in tests: skip where ROS is absent, fail where CI requires it.

``DISPEVAL_REQUIRE_ROS=1`` (set by ``.ci/run``, which installs the ROS 2 Jazzy wheels) turns
"rclpy absent" skips into failures, as ``DISPEVAL_REQUIRE_DATA`` does for the data: CI never
passes by skipping the node tests. ``launch``/``launch_testing`` are not on PyPI, so the launch
tests skip with their reason even there.
"""

from __future__ import annotations

import importlib
import os
import time
from collections.abc import Callable
from types import ModuleType
from typing import Any

import pytest

ROS_REQUIRED = os.environ.get("DISPEVAL_REQUIRE_ROS") == "1"


def ros_import(name: str) -> ModuleType:
    """Import a ROS 2 module, or skip the test module (fail under DISPEVAL_REQUIRE_ROS=1)."""
    try:
        return importlib.import_module(name)
    except ImportError as error:
        reason = f"ROS 2 module {name} is not importable ({error}); see README 'ROS 2 nodes'"
        if ROS_REQUIRED:
            pytest.fail(f"DISPEVAL_REQUIRE_ROS=1 but {reason}", pytrace=False)
        pytest.skip(reason, allow_module_level=True)


TIMEOUT = 60.0


class Ros:
    """One rclpy context (its own domain) with an executor, a helper node, and nodes under test.

    ``evaluator_class`` / ``summarizer_class`` are the project's node classes (imported by the
    test module, so that an import error in them fails rather than skips).
    """

    def __init__(self, domain_id: int, evaluator_class: Any, summarizer_class: Any) -> None:
        rclpy = ros_import("rclpy")
        self._rclpy = rclpy
        self._parameter = ros_import("rclpy.parameter").Parameter
        self._classes = {"evaluator": evaluator_class, "summarizer": summarizer_class}
        self.context = ros_import("rclpy.context").Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        executors = ros_import("rclpy.executors")
        self.executor = executors.SingleThreadedExecutor(context=self.context)
        self.helper = rclpy.create_node("dispeval_test_helper", context=self.context)
        self.executor.add_node(self.helper)
        self.nodes: list[Any] = []

    def add(self, node: Any) -> Any:
        self.executor.add_node(node)
        self.nodes.append(node)
        return node

    def _node(self, kind: str, parameters: dict[str, Any]) -> Any:
        overrides = [self._parameter(name, value=value) for name, value in parameters.items()]
        return self.add(self._classes[kind](context=self.context, parameter_overrides=overrides))

    def evaluator(self, **parameters: Any) -> Any:
        return self._node("evaluator", parameters)

    def summarizer(self, **parameters: Any) -> Any:
        return self._node("summarizer", parameters)

    def collect(self, msg_type: Any, topic: str, qos: Any, raw: bool = False) -> list[Any]:
        received: list[Any] = []
        self.helper.create_subscription(msg_type, topic, received.append, qos, raw=raw)
        return received

    def spin_until(self, condition: Callable[[], bool], timeout: float = TIMEOUT) -> bool:
        deadline = time.monotonic() + timeout
        while not condition() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
        return condition()

    def spin_for(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)

    def destroy(self, node: Any) -> None:
        node.finish()
        self.executor.remove_node(node)
        self.nodes.remove(node)
        node.destroy_node()

    def close(self) -> None:
        for node in list(self.nodes):
            self.destroy(node)
        self.executor.shutdown()
        self.helper.destroy_node()
        self._rclpy.try_shutdown(context=self.context)


def input_types(config: Any) -> dict[str, Any]:
    """The rclpy message class of every input topic of a core configuration."""
    sensor_msgs = ros_import("sensor_msgs.msg")
    stereo_msgs = ros_import("stereo_msgs.msg")
    types = {config.gt_topic: sensor_msgs.Image}
    for info in (config.left_info_topic, config.right_info_topic):
        if info:
            types[info] = sensor_msgs.CameraInfo
    types.update(dict.fromkeys(config.methods.values(), stereo_msgs.DisparityImage))
    return types


def launch_unavailable() -> str | None:
    """Why the launch tests cannot run here (None if they can); never raises or skips.

    ``launch``/``launch_testing`` are not on PyPI, so these tests run under ``colcon test`` in a
    built ROS 2 workspace only; DISPEVAL_REQUIRE_ROS does not turn this skip into a failure. A
    launch test module must not skip while it is imported: launch_testing's pytest plugin
    imports it during collection, and a skip there ends the collection of every test.
    """
    for name in ("launch", "launch_ros.actions", "launch_testing", "ament_index_python.packages"):
        try:
            importlib.import_module(name)
        except ImportError as error:
            return f"{name} is not importable ({error}): launch tests run under colcon test"
    ament_index = importlib.import_module("ament_index_python.packages")
    try:
        ament_index.get_package_share_directory("dispeval_ros")
    except (ament_index.PackageNotFoundError, OSError):  # OSError: AMENT_PREFIX_PATH unset
        return (
            "dispeval_ros is not installed in a ROS 2 workspace (colcon build, then source "
            "install/setup.bash): launch cannot find its executables"
        )
    return None
