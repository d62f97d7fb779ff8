"""dispeval_ros: an ament_python package that also installs with plain ``pip install .``."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup
from setuptools.command.build_py import build_py

sys.path.insert(0, str(Path(__file__).resolve().parent))  # buildtools, also under colcon
from buildtools.requirements import requirements

PACKAGE = "dispeval_ros"
COMPILE_AHEAD = "from dispeval_ros.cli.compile_ahead import compile_ahead; compile_ahead()"


class BuildPyWithKernels(build_py):
    """build_py, then the numba kernels compiled into the built package.

    A fresh install then loads them on its first run instead of compiling for seconds
    (numba's cache is keyed by source content, interpreter and CPU, so this holds where the
    package is built and used on one machine, as ``pip install .`` and ``colcon build`` do;
    elsewhere the kernels compile on first use as before). Skipped, with a note, when the
    build environment cannot import the package (its requirements are missing) or when
    ``DISPEVAL_COMPILE_AHEAD=0``.
    """

    def run(self) -> None:
        super().run()
        skipped = os.environ.get("DISPEVAL_COMPILE_AHEAD") == "0" or self.dry_run
        if skipped or getattr(self, "editable_mode", False):  # editable: the source's own cache
            return
        env = {name: value for name, value in os.environ.items() if name != "NUMBA_CACHE_DIR"}
        env["PYTHONPATH"] = os.pathsep.join(
            [str(Path(self.build_lib).resolve()), *filter(None, [env.get("PYTHONPATH")])]
        )
        with tempfile.TemporaryDirectory() as folder:  # not the source tree: the built package
            try:
                done = subprocess.run(
                    [sys.executable, "-c", COMPILE_AHEAD],
                    cwd=folder,
                    env=env,
                    capture_output=True,
                    text=True,
                    timeout=900,
                    check=False,
                )
                failed = done.returncode != 0 and (done.stderr.strip().splitlines() or ["?"])[-1]
            except (OSError, subprocess.TimeoutExpired) as error:
                failed = str(error)
        if failed:
            print(
                f"dispeval_ros: kernels not compiled ahead ({failed}); they compile on first use",
                file=sys.stderr,
            )


DDS = ["cyclonedds>=0.10.5"]
REPORT = ["matplotlib>=3.5"]
DASK = ["dask[distributed]>=2023.1"]
# pytest 9 aborts every run once launch_testing (part of any ROS 2 install) is importable.
# moocore: reference non-dominated sorting for bench/bench_models.py (never imported by the package)
TEST = [
    "pytest>=7,<9",
    "setuptools>=61",  # test_jitcache builds the wheel without build isolation
    "wheel",
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
            "testbed_disparity = dispeval_ros.ros.testbed_disparity:main",
        ]
    return scripts


setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=[PACKAGE, f"{PACKAGE}.*"]),
    package_data={PACKAGE: ["py.typed", "report/assets/*", "report/assets/js/*"]},
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
        "dev": [*TEST, "ruff>=0.5", "mypy>=1.8", "import-linter>=2.0"],
    },
    zip_safe=True,
    maintainer="dispeval_ros developers",
    maintainer_email="dispeval-ros@example.org",
    description="Evaluate stereo disparity maps by set-partition criteria, SZE/BMPRE and Pareto models.",
    license="Apache-2.0",
    cmdclass={"build_py": BuildPyWithKernels},
    entry_points={"console_scripts": console_scripts()},
)
