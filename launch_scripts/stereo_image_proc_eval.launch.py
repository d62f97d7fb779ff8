"""Example: evaluate stereo_image_proc's disparity output against a ground-truth topic.

    sudo apt install ros-$ROS_DISTRO-stereo-image-proc     # (and -rosbag2-storage-mcap on Humble)
    ros2 launch dispeval_ros stereo_image_proc_eval.launch.py
    ros2 launch dispeval_ros stereo_image_proc_eval.launch.py bag:=my_drive/ config:=my.yaml
    ros2 launch dispeval_ros stereo_image_proc_eval.launch.py bag:=""   # live cameras + GT

``ros2 bag play`` publishes the recording (by default the bundled sample bag: rectified mono8
images, CameraInfo, ground-truth disparity and four recorded OpenCV methods);
stereo_image_proc's ``disparity_node`` runs in the namespace ``/stereo`` and publishes
``/stereo/disparity``; the evaluator (parameters: ``config``, default the installed
config/stereo_image_proc.yaml) scores it beside the recorded methods and the summarizer groups
them. When the playback ends the launch waits ``settle`` seconds for the last disparities, then
shuts down: the evaluator publishes its last frames and the summarizer writes its files.
"""

from __future__ import annotations

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchContext, LaunchDescription
from launch.actions import (
    DeclareLaunchArgument,
    ExecuteProcess,
    OpaqueFunction,
    RegisterEventHandler,
    Shutdown,
    TimerAction,
)
from launch.event_handlers import OnProcessExit
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

PACKAGE = "dispeval_ros"
SIGTERM_TIMEOUT = "30"


def generate_launch_description() -> LaunchDescription:
    """The launch arguments, the playback, stereo_image_proc and both dispeval nodes."""
    share = get_package_share_directory(PACKAGE)
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                "bag",
                default_value=os.path.join(share, "bags", "sample_drive"),
                description="recording to play with ros2 bag play (empty: live topics)",
            ),
            DeclareLaunchArgument("rate", default_value="1.0", description="ros2 bag play --rate"),
            DeclareLaunchArgument(
                "settle",
                default_value="3.0",
                description="seconds to wait after the playback before shutting down",
            ),
            DeclareLaunchArgument(
                "config",
                default_value=os.path.join(share, "config", "stereo_image_proc.yaml"),
                description="parameter file of dispeval_evaluator and dispeval_summarizer",
            ),
            DeclareLaunchArgument(
                "output_dir",
                default_value="",
                description="summarizer results folder (empty: the file's 'output_dir')",
            ),
            OpaqueFunction(function=_actions),
        ]
    )


def _actions(context: LaunchContext) -> list[object]:
    config = LaunchConfiguration("config").perform(context)
    bag = LaunchConfiguration("bag").perform(context)
    output_dir = LaunchConfiguration("output_dir").perform(context)
    summarizer_parameters: list[str | dict[str, ParameterValue]] = [config]
    if output_dir:
        summarizer_parameters.append({"output_dir": ParameterValue(output_dir, value_type=str)})
    actions: list[object] = [
        Node(
            package="stereo_image_proc",
            executable="disparity_node",
            name="disparity_node",
            namespace="stereo",
            output="screen",
        ),
        Node(
            package=PACKAGE,
            executable="evaluator",
            name="dispeval_evaluator",
            parameters=[config],
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
    if bag:
        play = ExecuteProcess(
            cmd=["ros2", "bag", "play", bag, "--rate", LaunchConfiguration("rate")],
            name="bag_play",
            output="screen",
        )
        settle = float(LaunchConfiguration("settle").perform(context))
        actions += [
            # Let the nodes subscribe before the first message is played.
            TimerAction(period=2.0, actions=[play]),
            RegisterEventHandler(
                OnProcessExit(
                    target_action=play,
                    on_exit=[
                        TimerAction(
                            period=settle,
                            actions=[Shutdown(reason="the recording has been played")],
                        )
                    ],
                )
            ),
        ]
    return actions
