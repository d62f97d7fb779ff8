"""dispeval_ros: an ament_python package that also installs with plain ``pip install .``."""

from __future__ import annotations

import importlib.util
import os
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "dispeval_ros"


def requirements() -> list[str]:
    """Runtime requirements for pip; none declared to setuptools in a ROS build.

    Under ``colcon build`` (``AMENT_PREFIX_PATH`` set) package.xml and rosdep provide the
    dependencies (numba, OpenCV from apt have other distribution names or older versions), and
    Humble's setuptools would make the node scripts refuse to start over a name mismatch.
    OpenCV is required only when no cv2 (e.g. ROS's python3-opencv) is importable.
    """
    if os.environ.get("AMENT_PREFIX_PATH"):
        return ["setuptools"]
    required = [
        "numpy>=1.21",
        "numba>=0.55",
        "rosbags>=0.11",
        "mcap>=1.2",
        "mcap-ros2-support>=0.5",
    ]
    if importlib.util.find_spec("cv2") is None:
        required.append("opencv-python-headless>=4.5")
    return required


DDS = ["cyclonedds>=0.10.5"]
REPORT = ["matplotlib>=3.5"]
DASK = ["dask[distributed]>=2023.1"]
# pytest 9 aborts every run once launch_testing (part of any ROS 2 install) is importable.
# moocore: reference non-dominated sorting for bench/bench_models.py (never imported by the package)
TEST = [
    "pytest>=7,<9",
    "hypothesis>=6",
    "pillow>=9",
    "playwright>=1.40",
    "moocore>=0.3",
    *DDS,
    *REPORT,
    *DASK,
]


def console_scripts() -> list[str]:
    """``dispeval`` always; the ROS node executables only when building in a ROS environment.

    ``colcon build`` runs with ``AMENT_PREFIX_PATH`` set; the nodes then land in
    ``lib/dispeval_ros`` (see setup.cfg) where ``ros2 run dispeval_ros evaluator`` finds them.
    A plain ``pip install .`` does not put commands named ``evaluator``/``summarizer`` on PATH.
    """
    scripts = ["dispeval = dispeval_ros.cli.main:main"]
    if os.environ.get("AMENT_PREFIX_PATH"):
        scripts += [
            "evaluator = dispeval_ros.ros.evaluator:main",
            "summarizer = dispeval_ros.ros.summarizer:main",
        ]
    return scripts


setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*", "bench"]),
    package_data={PACKAGE: ["py.typed", "report/assets/*"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", glob("launch_scripts/*.launch.py")),
        (f"share/{PACKAGE}/config", glob("config/*.yaml") + glob("config/*.xml")),
        (f"share/{PACKAGE}/bags/sample_drive", glob("bags/sample_drive/*")),
    ],
    python_requires=">=3.10",
    install_requires=requirements(),
    extras_require={
        "dds": DDS,
        "report": REPORT,
        "dask": DASK,
        "test": TEST,
        "dev": [*TEST, "ruff>=0.5", "mypy>=1.8"],
    },
    zip_safe=True,
    maintainer="dispeval_ros developers",
    maintainer_email="dispeval-ros@example.org",
    description="Evaluate stereo disparity maps by set-partition criteria, SZE/BMPRE and Pareto models.",
    license="Apache-2.0",
    entry_points={"console_scripts": console_scripts()},
)
