"""The bundled sample bag: where it is (source tree or installed share/), or make it anew."""

from __future__ import annotations

from pathlib import Path

from dispeval_ros.io.share import shared_file_candidates

SAMPLE_NAME = "sample_drive"
SAMPLE_FRAMES = 25
SAMPLE_SIZE = (384, 112)
SAMPLE_METHODS = ("bm_fast", "bm_smooth", "sgbm", "sgbm_3way")
SAMPLE_FPS = 10.0
#: The sample's LiDAR publishes the forward 120° of its turn (keeps the bag a few MB).
SAMPLE_LIDAR_FOV = 120.0


def find_sample_bag() -> Path | None:
    """The installed or checked-out sample bag folder, if present."""
    for candidate in shared_file_candidates(f"bags/{SAMPLE_NAME}/metadata.yaml"):
        if candidate.is_file():
            return candidate.parent
    return None


def make_sample_bag(path: Path) -> Path:
    """Write the sample bag (a few seconds of synthetic driving, reduced resolution)."""
    from dispeval_ros.offline.make_bag import synthetic_frames, write_bag
    from dispeval_ros.testbed import default_methods
    from dispeval_ros.testbed.lidar import LidarModel

    width, height = SAMPLE_SIZE
    methods = [m for m in default_methods(width) if m.name in SAMPLE_METHODS]
    lidar = LidarModel(horizontal_fov=SAMPLE_LIDAR_FOV)
    # The bundled bag predates the drive's /tf: regenerate it (and its digest test) to add it.
    frames = synthetic_frames(
        SAMPLE_FRAMES, width, height, SAMPLE_FPS, seed=0, lidar=lidar, odometry=False
    )
    write_bag(path, frames, storage="rosbag2-mcap", methods=methods, fps=SAMPLE_FPS, compress=True)
    return path
