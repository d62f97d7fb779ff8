"""The bundled sample bag: where it is (source tree or installed share/), or make it anew."""

from __future__ import annotations

import sys
from importlib import metadata
from pathlib import Path

SAMPLE_NAME = "sample_drive"
SAMPLE_FRAMES = 25
SAMPLE_SIZE = (384, 112)
SAMPLE_METHODS = ("bm_fast", "bm_smooth", "sgbm", "sgbm_3way")
SAMPLE_FPS = 10.0
#: The sample's LiDAR publishes the forward 120° of its turn (keeps the bag a few MB).
SAMPLE_LIDAR_FOV = 120.0


def _candidates() -> list[Path]:
    here = Path(__file__).resolve()
    found = [here.parents[2] / "bags" / SAMPLE_NAME]  # source checkout or editable install
    found.append(Path(sys.prefix) / "share" / "dispeval_ros" / "bags" / SAMPLE_NAME)
    try:
        files = metadata.distribution("dispeval_ros").files or []
        found.extend(
            Path(str(file.locate())).parent
            for file in files
            if f"bags/{SAMPLE_NAME}/" in str(file).replace("\\", "/")
        )
    except metadata.PackageNotFoundError:
        pass
    return found


def find_sample_bag() -> Path | None:
    """The installed or checked-out sample bag folder, if present."""
    for candidate in _candidates():
        if (candidate / "metadata.yaml").is_file():
            return candidate
    return None


def make_sample_bag(path: Path) -> Path:
    """Write the sample bag (a few seconds of synthetic driving, reduced resolution)."""
    from dispeval_ros.offline.make_bag import synthetic_frames, write_bag
    from dispeval_ros.testbed import default_methods
    from dispeval_ros.testbed.lidar import LidarModel

    width, height = SAMPLE_SIZE
    methods = [m for m in default_methods(width) if m.name in SAMPLE_METHODS]
    lidar = LidarModel(horizontal_fov=SAMPLE_LIDAR_FOV)
    frames = synthetic_frames(SAMPLE_FRAMES, width, height, SAMPLE_FPS, seed=0, lidar=lidar)
    write_bag(path, frames, storage="rosbag2-mcap", methods=methods, fps=SAMPLE_FPS, compress=True)
    return path
