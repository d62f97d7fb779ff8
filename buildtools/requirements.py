"""The runtime requirements, for ``setup.py`` and for the build environment of a wheel."""

from __future__ import annotations

import importlib.metadata
import importlib.util
import os


def requirements() -> list[str]:
    """Runtime requirements for pip; none declared to setuptools in a ROS build.

    Under ``colcon build`` (``AMENT_PREFIX_PATH`` set) package.xml and rosdep provide the
    dependencies (numba, OpenCV from apt have other distribution names or older versions), and
    Humble's setuptools would make the node scripts refuse to start over a name mismatch.
    OpenCV is required unless another cv2 (e.g. ROS's python3-opencv) is importable.
    """
    if os.environ.get("AMENT_PREFIX_PATH"):
        return ["setuptools"]
    required = [
        "numpy>=1.21",
        "numba>=0.55",
        "rosbags>=0.11",
        "mcap>=1.2",
        "mcap-ros2-support>=0.5",
        "blake3>=0.3",  # the stream digests (io/provenance.py; sha256, recorded as such, without)
        "pyyaml>=5.1",  # dispeval tune: space files, ROS 2 parameters files
    ]
    if _needs_opencv():
        required.append("opencv-python-headless>=4.5")
    return required


def _needs_opencv() -> bool:
    """No cv2, or the one of opencv-python-headless (a wheel's build environment has it)."""
    if importlib.util.find_spec("cv2") is None:
        return True
    try:
        importlib.metadata.distribution("opencv-python-headless")
    except importlib.metadata.PackageNotFoundError:
        return False  # another OpenCV: python3-opencv, opencv-python, opencv-contrib-python
    return True
