"""launch_testing: both nodes as processes, the sample bag replayed as fast as possible (ROS 2).

The evaluator replays ``bags/sample_drive`` (waiting for the summarizer to subscribe first),
publishes every frame and exits; a test waits for the latched ``/dispeval/groups``; after the
launch has shut down (SIGINT to the summarizer) the exit codes must be 0 and the summarizer's
results folder must hold frames of every method. Needs the package built in a ROS 2 workspace
(``colcon build``, then ``colcon test``); skipped elsewhere.
"""

from __future__ import annotations

import importlib
import os
import tempfile
import time
import unittest
from pathlib import Path
from typing import Any

import pytest
from ros_support import launch_unavailable

from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import GT_TOPIC, LEFT_INFO, RIGHT_INFO, disparity_topic
from dispeval_ros.offline.sample import SAMPLE_METHODS, SAMPLE_NAME, find_sample_bag

UNAVAILABLE = launch_unavailable()

if UNAVAILABLE is not None:

    def test_launch_needs_a_built_workspace() -> None:
        """Skipped at run time: a skip while launch_testing imports the module stops collection."""
        pytest.skip(UNAVAILABLE)

else:
    launch = importlib.import_module("launch")
    launch_ros_actions = importlib.import_module("launch_ros.actions")
    launch_testing = importlib.import_module("launch_testing")
    launch_testing_actions = importlib.import_module("launch_testing.actions")
    launch_testing_asserts = importlib.import_module("launch_testing.asserts")
    rclpy = importlib.import_module("rclpy")
    rclpy_context = importlib.import_module("rclpy.context")
    rclpy_executors = importlib.import_module("rclpy.executors")
    rclpy_qos = importlib.import_module("rclpy.qos")
    diagnostic_msgs = importlib.import_module("diagnostic_msgs.msg")

    DOMAIN_ID = 50 + (os.getpid() + 25) % 50
    """A domain of its own for the launched processes and the test's node."""
    TIMEOUT = 300.0
    """Seconds for the whole replay (the first frames include numba's compilation)."""

    def sample_bag() -> Path:
        """The sample bag of the source tree (colcon test runs in it), else the installed one."""
        source = Path(__file__).resolve().parents[2] / "bags" / SAMPLE_NAME
        if (source / "metadata.yaml").is_file():
            return source
        installed = find_sample_bag()
        assert installed is not None, "the sample bag is part of the package"
        return installed

    @pytest.mark.launch_test
    def generate_test_description() -> tuple[Any, dict[str, Any]]:
        """The evaluator replaying the sample bag as fast as possible, and the summarizer."""
        results = Path(tempfile.mkdtemp(prefix="dispeval-launch-test-")) / "results"
        environment = {"ROS_DOMAIN_ID": str(DOMAIN_ID)}
        evaluator = launch_ros_actions.Node(
            package="dispeval_ros",
            executable="evaluator",
            name="dispeval_evaluator",
            parameters=[
                {
                    "methods": [f"{m}:{disparity_topic(m)}" for m in SAMPLE_METHODS],
                    "gt_topic": GT_TOPIC,
                    "left_camera_info": LEFT_INFO,
                    "right_camera_info": RIGHT_INFO,
                    "bag": str(sample_bag()),
                    "bag_rate": 0.0,
                    "bag_wait_subscribers": 1,
                    "bag_exit": True,
                }
            ],
            additional_env=environment,
            output="screen",
        )
        summarizer = launch_ros_actions.Node(
            package="dispeval_ros",
            executable="summarizer",
            name="dispeval_summarizer",
            parameters=[{"output_dir": str(results), "summary_every": 10, "drain_timeout": 5.0}],
            additional_env=environment,
            output="screen",
        )
        description = launch.LaunchDescription(
            [evaluator, summarizer, launch_testing_actions.ReadyToTest()]
        )
        return description, {"evaluator": evaluator, "summarizer": summarizer, "results": results}

    class TestWhileRunning(unittest.TestCase):
        def test_groups_are_published(self) -> None:
            context = rclpy_context.Context()
            rclpy.init(context=context, domain_id=DOMAIN_ID)
            node = rclpy.create_node("dispeval_launch_test", context=context)
            executor = rclpy_executors.SingleThreadedExecutor(context=context)
            try:
                received: list[Any] = []
                latched = rclpy_qos.QoSProfile(
                    history=rclpy_qos.HistoryPolicy.KEEP_LAST,
                    depth=1,
                    reliability=rclpy_qos.ReliabilityPolicy.RELIABLE,
                    durability=rclpy_qos.DurabilityPolicy.TRANSIENT_LOCAL,
                )
                node.create_subscription(
                    diagnostic_msgs.DiagnosticArray, "/dispeval/groups", received.append, latched
                )
                executor.add_node(node)
                deadline = time.monotonic() + TIMEOUT
                while not received and time.monotonic() < deadline:
                    executor.spin_once(timeout_sec=0.1)
                assert received, "no /dispeval/groups"
                assert {status.name for status in received[-1].status} == set(SAMPLE_METHODS)
            finally:
                executor.shutdown()
                node.destroy_node()
                rclpy.try_shutdown(context=context)

        def test_evaluator_replays_the_bag_and_exits(self, proc_info: Any, evaluator: Any) -> None:
            proc_info.assertWaitForShutdown(process=evaluator, timeout=TIMEOUT)

    @launch_testing.post_shutdown_test()
    class TestAfterShutdown(unittest.TestCase):
        def test_exit_codes(self, proc_info: Any) -> None:
            launch_testing_asserts.assertExitCodes(proc_info)

        def test_results_hold_every_method(self, results: Path) -> None:
            with ResultsStore.open(results) as store:
                assert set(store.methods()) == set(SAMPLE_METHODS)
                (sequence,) = store.sequences()
                assert store.stamps(sequence)
                for method in SAMPLE_METHODS:
                    assert next(store.frame_rows(sequence, method), None) is not None, method
            assert (results / "frames.csv").is_file()
            assert (results / "summary.json").is_file()
