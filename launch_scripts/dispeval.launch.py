"""Start the dispeval evaluator and summarizer.

    ros2 launch dispeval_ros dispeval.launch.py
    ros2 launch dispeval_ros dispeval.launch.py config:=my_eval.yaml output_dir:=results/run1
    ros2 launch dispeval_ros dispeval.launch.py bag:=drive1/      # replay instead of live topics

``config`` is the evaluator's parameter file (default: the installed config/evaluator.yaml);
it is also given to the summarizer after ``summarizer_config``, so one file with both
``dispeval_evaluator:`` and ``dispeval_summarizer:`` sections configures both. When the
evaluator exits (end of a replay, or an error) the whole launch shuts down, so the summarizer
writes its files.
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
"""Seconds launch waits after SIGINT before SIGTERM: time to score and store the last frames."""


def generate_launch_description() -> LaunchDescription:
    """The launch arguments and both nodes."""
    config = os.path.join(get_package_share_directory(PACKAGE), "config")
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                "config",
                default_value=os.path.join(config, "evaluator.yaml"),
                description="evaluator parameter file (may also hold dispeval_summarizer:)",
            ),
            DeclareLaunchArgument(
                "summarizer_config",
                default_value=os.path.join(config, "summarizer.yaml"),
                description="summarizer parameter file",
            ),
            DeclareLaunchArgument(
                "bag",
                default_value="",
                description="replay this bag instead of subscribing (empty: the file's 'bag')",
            ),
            DeclareLaunchArgument(
                "output_dir",
                default_value="",
                description="summarizer results folder (empty: the file's 'output_dir')",
            ),
            OpaqueFunction(function=_nodes),
        ]
    )


def _nodes(context: LaunchContext) -> list[Node]:
    config = LaunchConfiguration("config").perform(context)
    summarizer_config = LaunchConfiguration("summarizer_config").perform(context)
    bag = LaunchConfiguration("bag").perform(context)
    output_dir = LaunchConfiguration("output_dir").perform(context)
    # Overrides only when given, so the files' values stand otherwise; str so that a path
    # such as "2024" is not read as a number.
    # A replay waits for the summarizer's subscription: frames scored before it would be lost.
    evaluator_parameters: list[str | dict[str, ParameterValue]] = [
        config,
        {"bag_wait_subscribers": ParameterValue(1, value_type=int)},
    ]
    if bag:
        evaluator_parameters.append({"bag": ParameterValue(bag, value_type=str)})
    summarizer_parameters: list[str | dict[str, ParameterValue]] = [summarizer_config, config]
    if output_dir:
        summarizer_parameters.append({"output_dir": ParameterValue(output_dir, value_type=str)})
    return [
        Node(
            package=PACKAGE,
            executable="evaluator",
            name="dispeval_evaluator",
            parameters=evaluator_parameters,
            output="screen",
            sigterm_timeout=SIGTERM_TIMEOUT,
            on_exit=[Shutdown(reason="the dispeval evaluator has exited")],
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
