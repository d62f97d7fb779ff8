"""Replay the bundled sample bag through the evaluator, with the summarizer grouping the methods.

    ros2 launch dispeval_ros replay_sample.launch.py
    ros2 launch dispeval_ros replay_sample.launch.py rate:=0.0 output_dir:=/tmp/sample_results

The evaluator reads ``share/dispeval_ros/bags/sample_drive`` (a 2.5 s synthetic drive with four
OpenCV methods) itself, waits for the summarizer to subscribe, replays it and exits; the launch
then shuts down and the summarizer writes ``results.sqlite``, ``frames.csv`` and
``summary.json``. Meanwhile ``/dispeval/scores``, ``/dispeval/NAME/vector`` and
``/dispeval/groups`` can be watched (rqt_runtime_monitor, PlotJuggler, Foxglove).
"""

from __future__ import annotations

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchContext, LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction, Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

PACKAGE = "dispeval_ros"
SIGTERM_TIMEOUT = "30"


def generate_launch_description() -> LaunchDescription:
    """The launch arguments and both nodes."""
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                "rate",
                default_value="1.0",
                description="replay speed: 1.0 recorded timing, 0.0 as fast as scoring allows",
            ),
            DeclareLaunchArgument(
                "output_dir",
                default_value="",
                description="results folder (empty: $ROS_HOME/dispeval/DATE-TIME)",
            ),
            DeclareLaunchArgument(
                "error_images",
                default_value="false",
                description="also publish /dispeval/NAME/error and error_color",
            ),
            OpaqueFunction(function=_nodes),
        ]
    )


def _nodes(context: LaunchContext) -> list[Node]:
    share = get_package_share_directory(PACKAGE)
    config = os.path.join(share, "config")
    output_dir = LaunchConfiguration("output_dir").perform(context)
    evaluator_overrides = {
        "bag": ParameterValue(os.path.join(share, "bags", "sample_drive"), value_type=str),
        "bag_rate": ParameterValue(LaunchConfiguration("rate"), value_type=float),
        "bag_wait_subscribers": 1,
        "bag_loop": False,
        "bag_exit": True,
        "error_images": ParameterValue(LaunchConfiguration("error_images"), value_type=bool),
    }
    summarizer_parameters: list[str | dict[str, ParameterValue]] = [
        os.path.join(config, "summarizer.yaml")
    ]
    if output_dir:
        summarizer_parameters.append({"output_dir": ParameterValue(output_dir, value_type=str)})
    return [
        Node(
            package=PACKAGE,
            executable="evaluator",
            name="dispeval_evaluator",
            parameters=[os.path.join(config, "evaluator.yaml"), evaluator_overrides],
            output="screen",
            sigterm_timeout=SIGTERM_TIMEOUT,
            on_exit=[Shutdown(reason="the sample bag has been evaluated")],
        ),
        Node(
            package=PACKAGE,
            executable="summarizer",
            name="dispeval_summarizer",
            parameters=summarizer_parameters,
            output="screen",
            sigterm_timeout=SIGTERM_TIMEOUT,
        ),
    ]
