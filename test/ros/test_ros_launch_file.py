"""launch_testing: the shipped ``dispeval.launch.py bag:=…`` stores every frame of the bag.

The replay must not start before the summarizer subscribes (it once lost up to 22 of the sample
bag's 25 frames in half of the launches). Runs under ``colcon test`` in a built workspace;
skipped elsewhere, saying why.
"""

from __future__ import annotations

import importlib
import os
import tempfile
import unittest
from pathlib import Path
from typing import Any

import pytest
from ros_support import launch_unavailable

from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import GT_TOPIC, LEFT_INFO, RIGHT_INFO, disparity_topic
from dispeval_ros.offline.sample import SAMPLE_FRAMES, SAMPLE_METHODS, find_sample_bag

UNAVAILABLE = launch_unavailable()

if UNAVAILABLE is not None:

    def test_launch_needs_a_built_workspace() -> None:
        """Skipped at run time: a skip while launch_testing imports the module stops collection."""
        pytest.skip(UNAVAILABLE)

else:
    launch = importlib.import_module("launch")
    launch_actions = importlib.import_module("launch.actions")
    launch_sources = importlib.import_module("launch.launch_description_sources")
    launch_testing = importlib.import_module("launch_testing")
    launch_testing_actions = importlib.import_module("launch_testing.actions")
    launch_testing_asserts = importlib.import_module("launch_testing.asserts")
    ament_index = importlib.import_module("ament_index_python.packages")

    DOMAIN_ID = 50 + (os.getpid() + 40) % 50

    @pytest.mark.launch_test
    def generate_test_description() -> tuple[Any, dict[str, Any]]:
        """``ros2 launch dispeval_ros dispeval.launch.py config:=… bag:=… output_dir:=…``."""
        folder = Path(tempfile.mkdtemp(prefix="dispeval-launch-file-"))
        results = folder / "results"
        config = folder / "evaluator.yaml"
        methods = ", ".join(f'"{m}:{disparity_topic(m)}"' for m in SAMPLE_METHODS)
        config.write_text(
            "dispeval_evaluator:\n  ros__parameters:\n"
            f"    methods: [{methods}]\n    gt_topic: {GT_TOPIC}\n"
            f"    left_camera_info: {LEFT_INFO}\n    right_camera_info: {RIGHT_INFO}\n"
            "    bag_rate: 0.0\n"
        )
        bag = find_sample_bag()
        assert bag is not None
        share = ament_index.get_package_share_directory("dispeval_ros")
        included = launch_actions.IncludeLaunchDescription(
            launch_sources.PythonLaunchDescriptionSource(
                os.path.join(share, "launch", "dispeval.launch.py")
            ),
            launch_arguments={
                "config": str(config),
                "bag": str(bag),
                "output_dir": str(results),
            }.items(),
        )
        description = launch.LaunchDescription(
            [
                launch_actions.SetEnvironmentVariable("ROS_DOMAIN_ID", str(DOMAIN_ID)),
                included,
                launch_testing_actions.ReadyToTest(),
            ]
        )
        return description, {"results": results}

    class TestWhileRunning(unittest.TestCase):
        def test_the_evaluator_ends_with_the_replay(self, proc_info: Any) -> None:
            # Its exit shuts the launch down (the summarizer stores everything on SIGINT): wait
            # for the evaluator only, or the launch may end before this test does.
            proc_info.assertWaitForShutdown(process="evaluator", timeout=300.0)

    @launch_testing.post_shutdown_test()
    class TestAfterShutdown(unittest.TestCase):
        def test_exit_codes(self, proc_info: Any) -> None:
            launch_testing_asserts.assertExitCodes(proc_info)

        def test_every_frame_of_the_bag_is_stored(self, results: Path) -> None:
            with ResultsStore.open(results) as store:
                (sequence,) = store.sequences()
                assert len(store.stamps(sequence)) == SAMPLE_FRAMES
                counts = store.match_counts(sequence)
                assert {m: c.matched for m, c in counts.items()} == dict.fromkeys(
                    SAMPLE_METHODS, SAMPLE_FRAMES
                )
