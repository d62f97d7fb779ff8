"""Importing ROS 2 modules in tests: skip where ROS is absent, fail where CI requires it.

``DISPEVAL_REQUIRE_ROS=1`` (set by ``.ci/run``, which installs the ROS 2 Jazzy wheels) turns
"rclpy absent" skips into failures, as ``DISPEVAL_REQUIRE_DATA`` does for the data: CI never
passes by skipping the node tests. ``launch``/``launch_testing`` are not on PyPI, so the launch
tests skip with their reason even there.
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType

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
