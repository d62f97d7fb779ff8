"""Shared fixtures: the real stereo data in ../shared/data.

Tests that need the data use the ``shared_data`` fixture. Where the data is absent (a user's
clone) they skip with the reason; with ``DISPEVAL_REQUIRE_DATA=1`` (set by ``.ci/run``) a
missing data folder is a failure, so CI never passes by skipping.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]


def _data_root() -> Path:
    configured = os.environ.get("DISPEVAL_DATA")
    return Path(configured) if configured else REPO_ROOT.parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Root of the real data sets, or skip (fail under DISPEVAL_REQUIRE_DATA=1) if absent."""
    root = _data_root()
    if not (root / "README.md").is_file():
        reason = (
            f"real stereo data not found at {root}: put the shared data folder (Middlebury, "
            "MiddEval3, KITTI, ETH3D scenes; see README 'Extras') there or set DISPEVAL_DATA "
            "to its path"
        )
        if os.environ.get("DISPEVAL_REQUIRE_DATA") == "1":
            pytest.fail(f"DISPEVAL_REQUIRE_DATA=1 but {reason}")
        pytest.skip(reason)
    return root


@pytest.fixture
def ros() -> Iterator[Any]:
    """The rclpy harness of the node tests (ros_nodes_support.py), closed after each test.

    Imported here, not at the top: it skips (or fails under DISPEVAL_REQUIRE_ROS=1) without rclpy.
    """
    from ros_nodes_support import ros_harness

    harness = ros_harness()
    try:
        yield harness
    finally:
        harness.close()
